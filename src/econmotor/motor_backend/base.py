"""The motor-backend contract (spec: motor_backends.md).

A backend trains, evaluates and deploys low-level motor policies (``train_policy``, ``evaluate_policy``,
``deploy_policy_handle``) and returns :class:`~econmotor.motor_backend.results.MotorTrainingResult` /
:class:`~econmotor.motor_backend.results.MotorEvalResult`. Every backend extends
:class:`MotorBackendBase`, which owns what they all share (SB3's ``BaseAlgorithm`` is the model)
and where each declares what differs (:mod:`.capabilities`): its capabilities, defaults,
``num_envs`` limits on the device it will use, final-policy and checkpoint files, datapack check
and the Ray resources of a sweep cell. The CLI asks these; it never looks a backend up by name
(run directories and seeds: :mod:`.run_dir`).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any, ClassVar, Protocol, runtime_checkable

import numpy as np

from econmotor.errors import ConfigError
from econmotor.motor_backend.capabilities import BackendCapabilities, HeldOutCadence, RunSize, ShadowEnv
from econmotor.motor_backend.results import MotorEvalResult, MotorTrainingResult
from econmotor.motor_backend.run_dir import (
    EVALUATION_FILE,
    RUN_CONFIG_FILE,
    TRAINING_EVAL_DIR,
    TRAINING_EVAL_SEED_OFFSET,
    new_run_dir,
)
from econmotor.objectives.economic_objective import EconomicObjectiveSpec
from econmotor.tasks.catalog import TaskCatalog, TaskSpec, load_catalog

#: progress(label, completed, total): backends report long work through this; the CLI draws bars.
ProgressFn = Callable[[str, float, float], None]



#: stop(rows so far, in seed order) -> True to end an evaluation (a sequential evaluation's looks).
StopFn = Callable[[list[dict[str, Any]]], bool]


def no_progress(label: str, completed: float, total: float) -> None:
    """The default progress callback: report nothing."""


@runtime_checkable
class PolicyHandle(Protocol):
    """A deployed policy: observation(s) in, action(s) out; ``step(obs)`` is ``act(obs)``
    (upstream's deployed handles answer both); ``obs_dim`` is the observation width it takes."""

    obs_dim: int

    def act(self, obs: np.ndarray) -> np.ndarray: ...

    def step(self, obs: np.ndarray) -> np.ndarray: ...


class StepAlias:
    """Mixin for policy handles: ``step(obs, ...)`` returns ``act(obs, ...)`` (the upstream name)."""

    def step(self, obs: np.ndarray, *args: Any, **kwargs: Any) -> np.ndarray:
        """The same action(s) as ``act(obs, ...)``."""
        return self.act(obs, *args, **kwargs)  # type: ignore[attr-defined]


# --- the contract every backend extends ------------------------------------------------------

class MotorBackendBase:
    """The base class of every motor backend: the contract in one place.

    A subclass sets ``name`` and the declarations below and implements ``train_policy``,
    ``evaluate_policy`` and ``deploy_policy_handle``; it constructs with keyword arguments,
    ``task_files`` (extra task catalog YAML files) and ``runs_dir`` (where default run
    directories go) first, then its own.

    Class attributes (declarations the CLI reads; override in the subclass):
        name: the factory name.
        capabilities: :class:`BackendCapabilities`.
        defaults: the size of a request that gives neither ``--num-envs`` nor ``--max-steps``.
        smoke_run: the smallest request that exercises train -> export -> evaluate end to end
            (the contract test uses it for every registered backend).
        max_num_envs: the most environments the backend can be asked for on any device;
            :meth:`num_envs_note` says how a request is adapted on this machine.
        final_policy_file: the file a complete run directory holds (its presence marks a run done).
        checkpoint_glob: checkpoint files under ``<run>/checkpoints``, one pattern or several (None: no
            checkpoints).
        environment_options: environment variable -> constructor keyword. A backend never reads the
            environment itself; the edge (the CLI) reads these and passes them
            (:func:`econmotor.motor_backend.factory.environment_options`).
        held_out_cadence: the default cadence of evaluation-driven training's held-out evaluations
            (:class:`HeldOutCadence`; ``capabilities.evaluation_driven`` backends).
    """

    name: ClassVar[str] = "base"
    capabilities: ClassVar[BackendCapabilities] = BackendCapabilities()
    defaults: ClassVar[RunSize] = RunSize(num_envs=1, max_steps=10_000)
    smoke_run: ClassVar[RunSize] = RunSize(num_envs=1, max_steps=256)
    max_num_envs: ClassVar[int] = 256
    final_policy_file: ClassVar[str] = "policy.zip"
    checkpoint_glob: ClassVar[str | tuple[str, ...] | None] = None
    environment_options: ClassVar[Mapping[str, str]] = {}
    held_out_cadence: ClassVar[HeldOutCadence] = HeldOutCadence()

    def __init__(self, *, task_files: Sequence[str | Path] = (), runs_dir: str | Path = "runs",
                 catalog: TaskCatalog | None = None) -> None:
        self.task_files = [Path(f) for f in task_files]
        #: the task catalog (the factory hands over the one a command checked; else parsed here)
        self.catalog = catalog if catalog is not None else load_catalog(self.task_files)
        self.runs_dir = Path(runs_dir)

    # --- declarations asked before any work ---------------------------------------------------
    @classmethod
    def shadow_env(cls, spec: TaskSpec, max_episode_steps: int | None = None,
                   econ_overrides: Mapping[str, Any] | None = None) -> ShadowEnv:
        """One Gymnasium env of task ``spec`` for shadow mode (where ``capabilities.shadow_env``):
        ``max_episode_steps`` overrides the episode length, ``econ_overrides`` the backend's own
        economic parameters where it has any (a ConfigError where it has none)."""
        raise ConfigError("--env", spec.task_id, f"the '{cls.name}' backend builds no single Gymnasium env")

    @classmethod
    def robot_id(cls, spec: TaskSpec) -> str:
        """The robot task ``spec`` runs on, named apart from any backend: the registry's robot id, the same
        for one robot on every backend that runs it (``hopper``, ``g1_29dof``, ...). A subclass answers it
        from the task's entry (its robot card or model); the base, for tasks that name no robot, answers
        the task id."""
        return spec.task_id

    @classmethod
    def check_num_envs(cls, num_envs: int | None, flag: str = "--num-envs") -> None:
        """``num_envs`` must be within :attr:`max_num_envs`; a ConfigError names the flag and the limit."""
        if num_envs is not None and num_envs > cls.max_num_envs:
            raise ConfigError(flag, None, f"{num_envs:,} is more than the '{cls.name}' backend can run",
                              f"0 (the task's default) to {cls.max_num_envs:,}")

    def num_envs_note(self, task_id: str, num_envs: int) -> str | None:
        """How a request for ``num_envs`` environments is adapted on this machine (None: as asked)."""
        return None

    @classmethod
    def check_datapack(cls, pack: Any, source: str) -> None:
        """Raise a ConfigError when ``pack``'s randomization or curriculum cannot be used by this backend
        (the base accepts what the generic datapack schema accepted)."""

    @classmethod
    def check_task_entry(cls, spec: Any) -> None:
        """Raise a ConfigError naming the task file and key when ``spec``'s (a catalog ``TaskSpec``)
        ``backends.<name>`` entry has keys or values this backend cannot use. The catalog calls it
        when a user task file is loaded; the base accepts any mapping."""

    @classmethod
    def sweep_resources(cls) -> dict[str, float]:
        """The Ray resources one sweep cell of this backend needs (``num_cpus``, ``num_gpus``)."""
        return {"num_cpus": 1.0, "num_gpus": 0.0}

    def evaluation_batch(self, task_id: str) -> int:
        """Episodes this backend evaluates together (one batched rollout, or one per worker process): the
        first look of a sequential evaluation, and how often ``evaluate_policy`` asks ``stop``."""
        return 16

    def device_description(self) -> str | None:
        """The device training runs on, in words (None: the CPU, nothing to announce)."""
        return None

    # --- run directories -------------------------------------------------------------------------
    def run_dir(self, output_dir: str | Path | None, task_id: str, seed: int) -> Path:
        """``output_dir`` (the run directory), else a new one under :attr:`runs_dir`."""
        return Path(output_dir) if output_dir is not None else new_run_dir(self.runs_dir, task_id, seed)

    @classmethod
    def is_complete_run(cls, run_dir: str | Path) -> bool:
        """``run_dir`` holds this backend's final policy and its ``run_config.json``."""
        return (Path(run_dir) / cls.final_policy_file).is_file() and (Path(run_dir) / RUN_CONFIG_FILE).is_file()

    @classmethod
    def checkpoints(cls, run_dir: str | Path) -> list[Path]:
        """The run's checkpoint files, oldest first (empty without checkpoints)."""
        folder = Path(run_dir) / "checkpoints"
        if cls.checkpoint_glob is None or not folder.is_dir():
            return []
        globs = (cls.checkpoint_glob,) if isinstance(cls.checkpoint_glob, str) else cls.checkpoint_glob
        return sorted({p for glob in globs for p in folder.glob(glob)}, key=lambda p: p.stat().st_mtime)

    def check_policy(self, policy_id: str) -> None:
        """Raise a ConfigError when ``policy_id`` cannot be evaluated by this backend, before any run is
        recorded (the base checks nothing; a backend with ``imported_policies`` checks files and names)."""

    def check_init_policy(self, policy: str, task_id: str) -> None:
        """Raise a ConfigError when ``policy`` (``--init-policy``) cannot start a run of ``task_id``, before any
        run is recorded. The base refuses: only a backend with ``capabilities.init_policies`` starts from one."""
        raise ConfigError("--init-policy", policy, f"the '{self.name}' backend cannot start from a policy trained "
                          "elsewhere")

    # --- the evaluation after training: one rule for every backend ---------------------------------
    def evaluate_after_training(self, run_dir: str | Path, task_id: str, objective: EconomicObjectiveSpec,
                                eval_episodes: int, seed: int, *, datapack_configs: Sequence[Any] | None = None,
                                progress: ProgressFn = no_progress, **options: Any) -> MotorEvalResult | None:
        """The evaluation right after training, the same for every backend: :meth:`evaluate_policy` on the run
        directory just written (``eval_episodes`` episodes seeded from ``seed + TRAINING_EVAL_SEED_OFFSET``),
        recorded in ``<run_dir>/eval/evaluation.json`` (:data:`TRAINING_EVAL_DIR`); None when ``eval_episodes``
        is 0. ``options``: ``evaluate_policy``'s own keywords (e.g. ``datapack_ids``)."""
        if eval_episodes <= 0:
            return None
        return self.evaluate_policy(str(run_dir), task_id, objective, eval_episodes, seed + TRAINING_EVAL_SEED_OFFSET,
                                    datapack_configs=datapack_configs, output_dir=Path(run_dir) / TRAINING_EVAL_DIR,
                                    progress=progress, **options)

    def training_result(self, run_dir: str | Path, task_id: str, evaluation: MotorEvalResult | None,
                        training_curve: list[dict[str, float]], config: Mapping[str, Any],
                        artifacts: Mapping[str, str]) -> MotorTrainingResult:
        """What ``train_policy`` returns: the run directory as ``policy_id`` and the metrics and episodes of
        :meth:`evaluate_after_training` (empty without one), whose config the run's ``config`` keeps under
        ``evaluation`` and whose ``evaluation.json`` its ``artifacts`` name."""
        config, artifacts = dict(config), dict(artifacts)
        if evaluation is None:
            return MotorTrainingResult(str(run_dir), task_id, self.name, {}, {}, [], training_curve, config, artifacts)
        config["evaluation"] = evaluation.config
        artifacts["evaluation"] = str(Path(run_dir) / TRAINING_EVAL_DIR / EVALUATION_FILE)
        return MotorTrainingResult(str(run_dir), task_id, self.name, evaluation.raw_metrics, evaluation.econ_metrics,
                                   evaluation.episodes, training_curve, config, artifacts)

    # --- the three operations (spec: motor_backends.md); a subclass implements each ---------------
    def train_policy(self, task_id: str, objective: EconomicObjectiveSpec, datapack_ids: Sequence[str],
                     num_envs: int, max_steps: int, seed: int, *, datapack_configs: Sequence[Any] | None = None,
                     output_dir: str | Path | None = None, eval_episodes: int = 5,
                     progress: ProgressFn = no_progress, **options: Any) -> MotorTrainingResult:
        """Train into ``output_dir`` (the run directory; :meth:`run_dir`), then :meth:`evaluate_after_training`
        and return :meth:`training_result`; ``options``: the backend's own."""
        raise NotImplementedError

    def evaluate_policy(self, policy_id: str, task_id: str, objective: EconomicObjectiveSpec, num_episodes: int,
                        seed: int, *, datapack_configs: Sequence[Any] | None = None,
                        output_dir: str | Path | None = None, progress: ProgressFn = no_progress,
                        stop: StopFn | None = None, **options: Any) -> MotorEvalResult:
        """``num_episodes`` deterministic episodes of ``policy_id`` (episode i seeded ``seed + i``).

        ``stop(rows)``: called with the raw episodes finished so far, the first ``len(rows)`` in seed
        order, whenever a batch has ended (:meth:`evaluation_batch`); True ends the evaluation (a
        sequential evaluation, ``motor_backend/sequential.py``). Episodes beyond may be returned too."""
        raise NotImplementedError

    def deploy_policy_handle(self, policy_id: str) -> PolicyHandle:
        """A handle answering ``act(obs)`` and ``step(obs)`` for ``policy_id``."""
        raise NotImplementedError


#: the contract's name in the spec (motor_backends.md): every backend is a :class:`MotorBackendBase`.
