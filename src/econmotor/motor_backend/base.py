"""The motor-backend contract (spec: motor_backends.md).

A backend trains, evaluates and deploys low-level motor policies::

    train_policy(task_id, objective, datapack_ids, num_envs, max_steps, seed)
    evaluate_policy(policy_id, task_id, objective, num_episodes, seed)
    deploy_policy_handle(policy_id)

and returns :class:`MotorTrainingResult` / :class:`MotorEvalResult` carrying the
raw metrics of the motor stack, the econ metrics from
:class:`econmotor.economics.EconomicMeter`, and one summary per evaluation episode.
Every backend extends :class:`MotorBackendBase`, which owns what they all share (SB3's
``BaseAlgorithm`` is the model) and where each declares what differs: its capabilities,
defaults, ``num_envs`` limits on the device it will use, final-policy and checkpoint files,
datapack check and the Ray resources of a sweep cell. The CLI asks these; it never looks a
backend up by name.

One meaning everywhere: ``output_dir`` *is* the run directory (default: a new
``<runs_dir>/<task>-<UTC time>-s<seed>-<pid>``), its record is ``run_config.json``, and
``policy_id`` names that directory (or, for a backend that imports policies, a policy file
or shipped name), so any process can evaluate or deploy it. Evaluation seeds follow one
rule: episode ``i`` of an evaluation seeded ``s`` is seeded ``s + i``; the evaluation right
after training uses ``s = seed + TRAINING_EVAL_SEED_OFFSET``, a report's evaluation run
``s = seed + REPORT_EVAL_SEED_OFFSET`` and evaluation-driven training's held-out evaluations
``s = seed + SELECTION_SEED_OFFSET``, so none shares an episode with another.

Per-episode raw metrics use the meter's keys (``units_completed``, ``units_attempted``,
``errors``, ``episode_length_s``, ``energy_wh``, ``risk_score``, ``novelty_score``)
plus ``return`` and ``termination_reason``; :func:`summarize_episodes` turns them into
the aggregate raw metrics, the econ metrics and per-episode summaries that also carry
the RewardBuilder names (``mpl_episode``, ``error_rate_episode``, ``energy_Wh``,
``energy_Wh_per_unit``, ``wage_parity``).
"""

from __future__ import annotations

import json
import os
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar, NamedTuple, Protocol, runtime_checkable

import numpy as np

from econmotor.config.task_economics import TaskEconomics
from econmotor.economics.meter import EconomicMeter
from econmotor.errors import ConfigError
from econmotor.objectives.economic_objective import EconomicObjectiveSpec
from econmotor.tasks.catalog import TaskCatalog, TaskSpec, load_catalog

#: progress(label, completed, total): backends report long work through this; the CLI draws bars.
ProgressFn = Callable[[str, float, float], None]

#: raw per-episode keys that are summed when episodes are aggregated.
ADDITIVE_RAW_KEYS = ("units_completed", "units_attempted", "errors", "episode_length_s", "energy_wh")
#: raw per-episode keys that are averaged.
MEAN_RAW_KEYS = ("risk_score", "novelty_score", "return", "length_steps")


#: stop(rows so far, in seed order) -> True to end an evaluation (a sequential evaluation's looks).
StopFn = Callable[[list[dict[str, Any]]], bool]


def no_progress(label: str, completed: float, total: float) -> None:
    """The default progress callback: report nothing."""


@dataclass(frozen=True)
class MotorTrainingResult:
    """What ``train_policy`` returns.

    Attributes:
        policy_id: path of the saved policy; pass it to ``evaluate_policy`` / ``deploy_policy_handle``.
        task_id: the task trained on.
        backend: the backend's factory name.
        raw_metrics: aggregate raw metrics of the post-training evaluation episodes.
        econ_metrics: ``EconomicMeter.summarize(raw_metrics)``.
        episodes: one summary per evaluation episode (see :func:`summarize_episodes`).
        training_curve: ``[{"timesteps": int, "mean_return": float}, ...]`` during training.
        config: everything needed to reproduce the run (seed, objective, datapacks, hyperparameters).
        artifacts: named output files (policy, TensorBoard dir, ONNX, ...).
    """

    policy_id: str
    task_id: str
    backend: str
    raw_metrics: dict[str, float]
    econ_metrics: dict[str, float]
    episodes: list[dict[str, Any]] = field(default_factory=list)
    training_curve: list[dict[str, float]] = field(default_factory=list)
    config: dict[str, Any] = field(default_factory=dict)
    artifacts: dict[str, str] = field(default_factory=dict)


#: the key under which an evaluation's :class:`EvalProvenance` also travels in its ``config`` (and in
#: ``evaluation.json`` and the registry's run config): a result rebuilt from its config keeps it.
PROVENANCE_KEY = "provenance"


@dataclass(frozen=True)
class EvalProvenance:
    """How an evaluation's figures were made: what a report and ``compare`` say beside the economics.

    Every backend fills it in ``evaluate_policy``; what a backend does not measure stays None.

    Attributes:
        evaluator: the evaluator's short name ("sim2sim", "eval_agent", "mujoco", "mjx", "analytic").
        figures_from: where the figures come from, in words (simulator, model, policy format).
        imported: the policy was trained elsewhere (nothing was trained here).
        commanded_speed_m_per_s: the course's commanded speed, m/s (None: no commanded course).
        achieved_speed_m_per_s: the speed achieved while walking, m/s, weighted by walking time over the
            episodes (None: no course).
        mean_power_w: mean electrical power over the episodes, W (None: not metered).
        mean_mech_power_w: the mechanical power behind it, W (None: not metered).
    """

    evaluator: str = "unknown"
    figures_from: str = "not stated by the backend"
    imported: bool = False
    commanded_speed_m_per_s: float | None = None
    achieved_speed_m_per_s: float | None = None
    mean_power_w: float | None = None
    mean_mech_power_w: float | None = None

    def to_dict(self) -> dict[str, Any]:
        """The fields as a JSON-ready dict (what the registry and ``evaluation.json`` record)."""
        return dict(self.__dict__)

    @classmethod
    def from_dict(cls, values: Mapping[str, Any]) -> EvalProvenance:
        """The provenance :meth:`to_dict` recorded (unknown keys ignored)."""
        return cls(**{k: v for k, v in values.items() if k in cls.__dataclass_fields__})


@dataclass(frozen=True)
class MotorEvalResult:
    """What ``evaluate_policy`` returns (fields as in :class:`MotorTrainingResult`), plus ``provenance``
    (:class:`EvalProvenance`: which evaluator made the figures, speeds, power).

    ``config`` always carries the provenance too, under :data:`PROVENANCE_KEY`; a result built without
    ``provenance`` from a config that records one (e.g. a sequential evaluation rebuilding its result from
    the episodes it kept) takes it from there.
    """

    policy_id: str
    task_id: str
    backend: str
    raw_metrics: dict[str, float]
    econ_metrics: dict[str, float]
    episodes: list[dict[str, Any]] = field(default_factory=list)
    config: dict[str, Any] = field(default_factory=dict)
    provenance: EvalProvenance = field(default_factory=EvalProvenance)

    def __post_init__(self) -> None:
        recorded = self.config.get(PROVENANCE_KEY)
        if self.provenance == EvalProvenance() and recorded:
            object.__setattr__(self, "provenance", EvalProvenance.from_dict(recorded))
        object.__setattr__(self, "config", {**self.config, PROVENANCE_KEY: self.provenance.to_dict()})


def walking_speed_m_per_s(raw_episodes: Sequence[Mapping[str, Any]]) -> float | None:
    """The speed achieved while walking over episodes that walk a course (each with
    ``achieved_speed_m_per_s`` and ``walking_s``): ``sum(v_i * t_i) / sum(t_i)`` m/s, 0 when no episode
    walked; None when the episodes carry no speed (no course)."""
    if not raw_episodes or any("achieved_speed_m_per_s" not in e or "walking_s" not in e for e in raw_episodes):
        return None
    walking_s = sum(float(e["walking_s"]) for e in raw_episodes)
    return sum(float(e["achieved_speed_m_per_s"]) * float(e["walking_s"]) for e in raw_episodes) / walking_s \
        if walking_s > 0 else 0.0


def mean_power_w(raw_metrics: Mapping[str, Any]) -> float | None:
    """Mean electrical power of aggregated episodes, ``energy_wh / (episode_length_s / 3600)`` W (None:
    no energy metered; 0 for no time)."""
    if raw_metrics.get("energy_wh") is None:
        return None
    hours = float(raw_metrics.get("episode_length_s") or 0.0) / 3600.0
    return float(raw_metrics["energy_wh"]) / hours if hours > 0 else 0.0


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


#: the file every trained run directory (mujoco, mjx) starts with: its task, settings and hyperparameters
RUN_CONFIG_FILE = "run_config.json"
#: an evaluation's record in its output directory: metrics, episodes, config with the provenance
EVALUATION_FILE = "evaluation.json"


def read_run_config(run_dir: str | Path, backend: str | None = None, task_id: str | None = None) -> dict[str, Any]:
    """The ``run_config.json`` of a run directory; a ConfigError names what is wrong.

    ``backend``: the run must be that backend's (the ``backend`` every backend records with
    :func:`write_run_config`; None: any backend's run). ``task_id``: the policy must have been
    trained on it.
    """
    path = Path(run_dir) / RUN_CONFIG_FILE
    a_backend = f"{'an' if backend == 'mjx' else 'a'} {backend}" if backend else "a trained"  # "an mjx", "a mujoco"
    if not path.is_file():
        raise ConfigError(str(run_dir), None, f"not {a_backend} run directory (no {RUN_CONFIG_FILE})")
    config = json.loads(path.read_text(encoding="utf-8"))
    recorded = config.get("backend")
    if recorded is None:
        raise ConfigError(str(path), "backend", "missing: every backend records its name there (a run written by "
                          "hand or by an older econmotor); add the backend that trained it")
    if backend is not None and recorded != backend:
        raise ConfigError(str(path), "backend", f"a '{recorded}' run, not {a_backend} one")
    if task_id is not None and config.get("task_id") != task_id:
        raise ConfigError(str(path), "task_id", f"policy was trained on '{config.get('task_id')}', not '{task_id}'")
    return config


def write_run_config(run_dir: Path, config: Mapping[str, Any], backend: str) -> None:
    """Write ``run_config.json`` with ``backend`` recorded, atomically (a temporary file renamed over it):
    readers see the old or the new."""
    tmp = run_dir / (RUN_CONFIG_FILE + ".tmp")
    tmp.write_text(json.dumps({**config, "backend": backend}, indent=2, default=str), encoding="utf-8")
    tmp.replace(run_dir / RUN_CONFIG_FILE)


def check_resume_request(run_dir: Path, previous: Mapping[str, Any], task_id: str,
                         hyperparameters: Mapping[str, Any] | None) -> None:
    """A resumed run continues its recorded task and hyperparameters; asking for others is an error
    (start a new run directory to change them)."""
    source = str(run_dir / RUN_CONFIG_FILE)
    if previous.get("task_id") != task_id:
        raise ConfigError(source, "task_id", f"cannot resume a '{previous.get('task_id')}' run as '{task_id}'")
    recorded = previous.get("hyperparameters") or {}
    for key, value in (hyperparameters or {}).items():
        if key in recorded and recorded[key] != json.loads(json.dumps(value, default=str)):
            raise ConfigError(source, f"hyperparameters.{key}", f"the run was trained with {recorded[key]!r}; "
                              f"resume keeps the recorded value, not {value!r} (use a new --output-dir)")


def aggregate_raw(raw_episodes: Sequence[Mapping[str, Any]]) -> dict[str, float]:
    """Sum the additive keys and average the rest over episodes; adds ``num_episodes``."""
    out: dict[str, float] = {"num_episodes": float(len(raw_episodes))}
    if not raw_episodes:
        return out
    for key in ADDITIVE_RAW_KEYS:
        values = [float(ep[key]) for ep in raw_episodes if ep.get(key) is not None]
        if values:
            out[key] = float(np.sum(values))
    for key in MEAN_RAW_KEYS:
        values = [float(ep[key]) for ep in raw_episodes if ep.get(key) is not None]
        if values:
            out[key] = float(np.mean(values))
    return out


def episode_summary(raw_episode: Mapping[str, Any], meter: EconomicMeter, index: int) -> dict[str, Any]:
    """One episode's raw metrics plus its econ metrics and the RewardBuilder field names."""
    econ = meter.summarize(raw_episode, source=f"episode {index}")
    summary: dict[str, Any] = {"episode_index": index, **dict(raw_episode), **econ}
    summary.update(
        mpl_episode=econ["mpl_units_per_hour"],
        error_rate_episode=econ["error_rate"],
        energy_Wh=econ["energy_wh"],
        energy_Wh_per_unit=econ["energy_wh_per_unit"],
    )
    summary.setdefault("termination_reason", "max_steps")
    return summary


def summarize_episodes(
    raw_episodes: Sequence[Mapping[str, Any]], economics: TaskEconomics
) -> tuple[dict[str, float], dict[str, float], list[dict[str, Any]]]:
    """Return (aggregate raw metrics, econ metrics, per-episode summaries) of evaluation episodes.

    Aggregate econ metrics are ratios of sums (total good units / total hours, ...),
    not means of per-episode ratios.
    """
    meter = EconomicMeter(economics)
    raw = aggregate_raw(raw_episodes)
    econ = meter.summarize(raw) if raw_episodes else {}
    return raw, econ, [episode_summary(ep, meter, i) for i, ep in enumerate(raw_episodes)]


def evaluation_result(backend: str, policy_id: str, task_id: str, raw_episodes: Sequence[Mapping[str, Any]],
                      economics: TaskEconomics, config: Mapping[str, Any],
                      output_dir: str | Path | None = None,
                      provenance: EvalProvenance | None = None) -> MotorEvalResult:
    """The :class:`MotorEvalResult` of evaluation episodes (see :func:`summarize_episodes`); with
    ``output_dir``, also written there as ``evaluation.json`` (metrics, episodes, config with the
    provenance). ``provenance``: None keeps the one ``config`` records, if any."""
    raw, econ, episodes = summarize_episodes(raw_episodes, economics)
    result = MotorEvalResult(policy_id=str(policy_id), task_id=task_id, backend=backend, raw_metrics=raw,
                             econ_metrics=econ, episodes=episodes, config=dict(config),
                             provenance=provenance or EvalProvenance())
    if output_dir is not None:
        out = Path(output_dir)
        out.mkdir(parents=True, exist_ok=True)
        (out / EVALUATION_FILE).write_text(json.dumps(
            {"raw_metrics": raw, "econ_metrics": econ, "episodes": episodes, "config": result.config},
            indent=2, default=str), encoding="utf-8")
    return result


# --- the contract every backend extends ------------------------------------------------------

#: the evaluation right after training seeds its episodes from ``seed + TRAINING_EVAL_SEED_OFFSET``.
TRAINING_EVAL_SEED_OFFSET = 10_000
#: the evaluation right after training is recorded in ``<run_dir>/TRAINING_EVAL_DIR/evaluation.json``
#: (:data:`EVALUATION_FILE`).
TRAINING_EVAL_DIR = "eval"
#: a report's evaluation run seeds its episodes from ``seed + REPORT_EVAL_SEED_OFFSET`` (fresh episodes).
REPORT_EVAL_SEED_OFFSET = 1_000
#: held-out evaluations of evaluation-driven training (``selection.py``) seed episode i with
#: ``seed + SELECTION_SEED_OFFSET + i``: the same episodes for every checkpoint, apart from the others.
SELECTION_SEED_OFFSET = 50_000


def utc_stamp() -> str:
    """The UTC time to the second, ``YYYYmmdd-HHMMSS``: with the process id, a folder name no other run takes."""
    return time.strftime("%Y%m%d-%H%M%S", time.gmtime())


def new_run_dir(runs_dir: str | Path, task_id: str, seed: int) -> Path:
    """A run directory of its own: ``<runs_dir>/<task>-<UTC time>-s<seed>-<pid>`` (never reused)."""
    return Path(runs_dir) / f"{task_id}-{utc_stamp()}-s{seed}-{os.getpid()}"


@dataclass(frozen=True)
class BackendCapabilities:
    """What a backend can do beyond the three operations.

    Attributes:
        resume: ``train_policy(..., resume=True)`` continues an interrupted run from its checkpoints.
        algorithms: learners ``train_policy(..., algorithm=...)`` accepts (empty: the backend's own only).
        vec_env_kinds: vector-env kinds the constructor's ``vec_env`` accepts (empty: not selectable).
        imported_policies: ``evaluate_policy`` also takes policies trained elsewhere (a file or a
            shipped name), not only this backend's run directories.
        records_clips: ``record_clip(policy_id, path, num_steps, seed)`` saves a motion clip.
        evaluation_driven: held-out evaluations choose the checkpoint a run keeps, and training can
            stop once deployable (``motor_backend/selection.py``; ``--until-deployable``).
        init_policies: ``train_policy(..., init_policy=...)`` starts a new run's actor from a policy
            trained elsewhere (an ONNX file in Holosoma's format or a shipped name such as
            ``holosoma:g1_29dof/ppo``; ``--init-policy``) and fine-tunes it for the objective.
        shadow_env: :meth:`MotorBackendBase.shadow_env` builds one Gymnasium env of a task whose
            ``info["step_summary"]`` carries each step's economics (shadow mode, ``rl/``).
        course_speed: the evaluation walks a course at a commanded speed, and the constructor's
            ``course_speed_m_per_s`` (m/s; default: the task catalog's ``course_speed_m_per_s``) sets it
            (``compare --command-speed``).
    """

    resume: bool = False
    algorithms: tuple[str, ...] = ()
    vec_env_kinds: tuple[str, ...] = ()
    imported_policies: bool = False
    records_clips: bool = False
    evaluation_driven: bool = False
    init_policies: bool = False
    shadow_env: bool = False
    course_speed: bool = False


class ShadowEnv(NamedTuple):
    """One Gymnasium env of a task for shadow mode: ``info["step_summary"]`` every step, the
    episode's raw metrics at its end; ``dt_s`` seconds per step; ``max_episode_steps`` its limit."""

    env: Any
    dt_s: float
    max_episode_steps: int


@dataclass(frozen=True)
class HeldOutCadence:
    """When evaluation-driven training evaluates by default (``--select-every`` not given).

    Attributes:
        every_steps: env steps between held-out evaluations, at least (1: after any training iteration).
        max_share: and only once the training since the last one took at least ``(1 - max_share) /
            max_share`` times its cost (so by default they cost at most ~10% of a run, whatever the device).
    """

    every_steps: int = 25_000
    max_share: float = 0.10


@dataclass(frozen=True)
class RunSize:
    """A training request's size: ``num_envs`` (0: the task's catalog default) and ``max_steps``
    (environment steps); ``task_id`` where the size is meant for one task."""

    num_envs: int
    max_steps: int
    task_id: str | None = None

    def filled(self, num_envs: int | None, max_steps: int | None) -> RunSize:
        """A request's size: what it gives, this size for what it leaves out (None; ``num_envs`` 0 is
        the task's catalog default and stays 0). The one run-size rule of every command."""
        return RunSize(self.num_envs if num_envs is None else int(num_envs),
                       self.max_steps if max_steps is None else int(max_steps), self.task_id)


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
        checkpoint_glob: checkpoint files under ``<run>/checkpoints`` (None: no checkpoints).
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
    checkpoint_glob: ClassVar[str | None] = None
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
        return sorted(folder.glob(cls.checkpoint_glob), key=lambda p: p.stat().st_mtime)

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
MotorBackend = MotorBackendBase
