"""HolosomaBackend: Amazon FAR's Holosoma (G1/T1 humanoids) trained under an economic objective.

Holosoma pins numpy<2, so it lives in its own interpreter (``make holosoma`` builds
``.venv-holosoma`` from ``requirements-holosoma.txt``, econmotor included). This module
only plans and launches jobs there (:mod:`.jobs`); it imports neither Holosoma
nor torch, so it works in the main environment without Holosoma installed.

Task map: a task's ``backends.holosoma`` catalog entry names Holosoma's experiment preset per algorithm
(``humanoid_locomotion_g1`` -> ``g1_29dof`` / ``g1_29dof_fast_sac``, ...); a walker task's robot card, meter
and course are its locomotion block, the one every backend reads (:func:`econmotor.locomotion.task.task_settings`).

- **train_policy**: the objective compiles to overlay scales; each overlay key with a
  simulator term becomes a Holosoma reward term weighted ``overlay_gain * scale``
  (:mod:`econmotor.motor_backend.holosoma.venv.reward_terms`); datapacks become randomization / curriculum / terrain /
  motion-file overrides (:mod:`econmotor.couriers.datapack_mapping`); ``max_steps`` counts
  environment steps and is adapted to the simulator (:mod:`.plan`, every change
  announced as a ``holosoma: ...`` progress label and kept in ``config["messages"]``).
  Then ``eval_episodes`` episodes are evaluated.
- **evaluate_policy**: locomotion tasks, the sim-to-sim evaluator (:mod:`econmotor.locomotion.evaluation`:
  the policy's ONNX walking a delivery course in plain MuJoCo in this interpreter, metered by the
  couriers' formulas), for a
  run trained here and for an imported policy alike; whole-body tracking, Holosoma's ``eval_agent``
  with its recording callback (extended), raw metrics per episode from the recording
  (:mod:`.recording_metrics`).
- **deploy_policy_handle**: the onnxruntime handle (:mod:`econmotor.motor_backend.onnx_policy`) over
  Holosoma's exported ONNX, carrying Holosoma's metadata (``dof_names``, ``kp``, ``kd``, ``action_scale``, ...) and
  ours (``econmotor_*``: task, objective, overlay weights, task economics).

``output_dir`` is the run directory (default: a new one under ``runs_dir``); a trained run holds
``run_config.json`` and ``policy.onnx`` (:mod:`.run_record`). ``policy_id`` names that
directory, or an imported policy: an ONNX file in Holosoma's export format or a shipped one,
``holosoma:<robot>/<algo>`` (:mod:`econmotor.couriers.policy_import`).
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, ClassVar

from econmotor.config.datapacks import DatapackConfig, DatapackProvider
from econmotor.couriers.datapack_mapping import map_datapacks
from econmotor.couriers.policy_import import (
    NAME_PREFIX,
    VENV_ENV,
    find_holosoma_python,
    find_shipped_policy,
    is_imported_policy,
)
from econmotor.errors import BackendError, ConfigError
from econmotor.locomotion.task import locomotion_where, meter_settings, task_settings
from econmotor.motor_backend.base import MotorBackendBase, ProgressFn, StopFn, no_progress
from econmotor.motor_backend.capabilities import BackendCapabilities, RunSize
from econmotor.motor_backend.holosoma.econ_formulas import OVERLAY_TERM_KEYS
from econmotor.motor_backend.holosoma.host.jobs import run_job
from econmotor.motor_backend.holosoma.host.plan import (
    DEFAULT_CPU_MAX_ENV_STEPS,
    Capabilities,
    choose_simulator,
    plan_training,
)
from econmotor.motor_backend.holosoma.host.recording_metrics import episodes_from_recording
from econmotor.motor_backend.holosoma.host.run_record import read_run_record, record_run, training_log
from econmotor.motor_backend.holosoma.job_specs import EvaluateJob, Overlay, ProbeJob, TrainJob
from econmotor.motor_backend.onnx_policy import OnnxPolicyHandle
from econmotor.motor_backend.results import (
    EvalProvenance,
    MotorEvalResult,
    MotorTrainingResult,
    evaluation_result,
)
from econmotor.motor_backend.run_dir import RUN_CONFIG_FILE
from econmotor.motor_backend.walker_pricing import WalkerPricing, price_walker
from econmotor.objectives.economic_objective import EconomicObjectiveSpec, compile_economic_overlay
from econmotor.robots import card as robot_card
from econmotor.tasks.catalog import TaskCatalog

__all__ = ["HolosomaBackend", "find_holosoma_python"]

SIMULATOR_ENV = "ECONMOTOR_HOLOSOMA_SIMULATOR"
ALGO_ENV = "ECONMOTOR_HOLOSOMA_ALGO"
CPU_STEPS_ENV = "ECONMOTOR_HOLOSOMA_CPU_MAX_ENV_STEPS"


class HolosomaBackend(MotorBackendBase):
    """Holosoma through its own interpreter (module docstring).

    Args:
        task_files: user task catalog YAML files (added to the shipped catalog).
        runs_dir: where new run directories go when ``output_dir`` is not given.
        simulator: ``auto`` (default), ``isaacgym``, ``isaacsim``, ``mjwarp`` or ``mujoco`` (classic,
            CPU, one env). The CLI passes $ECONMOTOR_HOLOSOMA_SIMULATOR (``environment_options``).
        algo: ``ppo`` or ``fast_sac`` (else the task entry's ``algo``, else ppo; the CLI passes
            $ECONMOTOR_HOLOSOMA_ALGO).
        venv: the Holosoma virtualenv (default: see :func:`find_holosoma_python`; the CLI passes
            $ECONMOTOR_HOLOSOMA_VENV).
        cpu_max_env_steps: cap on environment steps when training on the CPU (the CLI passes
            $ECONMOTOR_HOLOSOMA_CPU_MAX_ENV_STEPS).
        eval_episode_length_s: evaluation episode length (default: sim-to-sim, the catalog's
            ``sim2sim_episode_s``; eval_agent, the preset's).
        course_speed_m_per_s: the sim-to-sim course's commanded speed (default: the catalog's
            ``course_speed_m_per_s``; the contract's keyword of ``capabilities.course_speed``).
        job_timeout_s: kill a job running longer than this.
        eval_workers: processes a sim-to-sim evaluation runs its episodes in (None: the CPUs this
            process may use: one worker per core); episode i is seeded ``seed + i`` whichever runs it.
    """

    name = "holosoma"
    capabilities = BackendCapabilities(algorithms=("ppo", "fast_sac"), imported_policies=True, course_speed=True)
    # Holosoma's own G1/T1 presets train 4096 envs on a GPU; the plan adapts a request to the machine
    defaults = RunSize(num_envs=0, max_steps=50_000)
    smoke_run = RunSize(num_envs=1, max_steps=240, task_id="humanoid_locomotion_g1")
    max_num_envs = 65_536
    final_policy_file = "policy.onnx"
    environment_options: ClassVar[Mapping[str, str]] = {VENV_ENV: "venv", SIMULATOR_ENV: "simulator",
                                                        ALGO_ENV: "algo", CPU_STEPS_ENV: "cpu_max_env_steps"}

    def __init__(
        self,
        *,
        task_files: Sequence[str | Path] = (),
        runs_dir: str | Path = "runs",
        catalog: TaskCatalog | None = None,
        simulator: str | None = None,
        algo: str | None = None,
        venv: str | Path | None = None,
        cpu_max_env_steps: int = DEFAULT_CPU_MAX_ENV_STEPS,
        eval_episode_length_s: float | None = None,
        course_speed_m_per_s: float | None = None,
        job_timeout_s: float | None = None,
        eval_workers: int | None = None,
    ) -> None:
        super().__init__(task_files=task_files, runs_dir=runs_dir, catalog=catalog)
        self.simulator = simulator or "auto"
        # an unknown simulator name fails here, before any job starts
        choose_simulator(self.simulator, Capabilities(cuda=True, isaacgym=True, isaacsim=True, mujoco_warp=True))
        self.algo = algo or None
        self.venv = venv
        self.cpu_max_env_steps = int(cpu_max_env_steps)
        self.eval_episode_length_s = eval_episode_length_s
        self.course_speed_m_per_s = course_speed_m_per_s
        self.job_timeout_s = job_timeout_s
        if eval_workers is not None and eval_workers < 1:
            raise ConfigError("<holosoma backend>", "eval_workers", f"must be >= 1, got {eval_workers}")
        self.eval_workers = int(eval_workers or (len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity")
                                                 else (os.cpu_count() or 1)))
        self._caps: Capabilities | None = None

    @classmethod
    def check_datapack(cls, pack: DatapackConfig, source: str) -> None:
        """The randomization, curriculum, terrain and motion-clip overrides a Holosoma run would apply."""
        bundle = DatapackProvider().resolve("<validate>", [pack.id], [pack])
        map_datapacks(bundle, [pack], uses_motion_clip=bool(pack.motion_clips))

    @classmethod
    def robot_id(cls, spec: Any) -> str:
        """The robot card the task's entry names (``g1_29dof``), for a policy trained here or imported alike."""
        return str(task_settings(spec)["robot"])

    @classmethod
    def check_task_entry(cls, spec: Any) -> None:
        """The ``backends.holosoma`` entry's keys, experiment and progress mode, and a walker task's locomotion
        block."""
        task_settings(spec)

    # -- helpers ---------------------------------------------------------------------------------
    @property
    def python(self) -> Path:
        return find_holosoma_python(self.venv)

    def machine(self, run_dir: Path) -> Capabilities:
        """What the Holosoma interpreter can use (probed once per backend)."""
        if self._caps is None:
            outcome = run_job(self.python, ProbeJob(), run_dir, no_progress, self.job_timeout_s)
            self._caps = Capabilities.from_dict(outcome.result)
        return self._caps

    def _task(self, task_id: str) -> tuple[Any, dict[str, Any]]:
        spec = self.catalog.get(task_id)
        return spec, task_settings(spec)

    @staticmethod
    def _overlay(objective: EconomicObjectiveSpec, gain: float) -> tuple[dict[str, float], list[str]]:
        overlay = compile_economic_overlay(objective)
        weights = {k: gain * s for k, s in overlay.items() if k in OVERLAY_TERM_KEYS}
        messages = [f"objective key '{k}' (scale {s}) has no Holosoma simulator term; ignored in training"
                    for k, s in overlay.items() if k not in OVERLAY_TERM_KEYS]
        return weights, messages

    # -- the protocol ----------------------------------------------------------------------------
    def train_policy(
        self,
        task_id: str,
        objective: EconomicObjectiveSpec,
        datapack_ids: Sequence[str],
        num_envs: int,
        max_steps: int,
        seed: int,
        *,
        datapack_configs: Sequence[DatapackConfig] | None = None,
        output_dir: str | Path | None = None,
        eval_episodes: int = 5,
        progress: ProgressFn = no_progress,
    ) -> MotorTrainingResult:
        """Train with Holosoma (plus the econ overlay), then evaluate ``eval_episodes`` episodes."""
        spec, settings = self._task(task_id)
        algo = self.algo or settings.get("algo", "ppo")
        if algo not in settings["experiment"]:
            raise ConfigError(spec.source, f"tasks.{task_id}.backends.holosoma.experiment",
                              f"no Holosoma preset for algorithm '{algo}'", list(settings["experiment"]))
        packs = list(datapack_configs or ())
        bundle = DatapackProvider().resolve(task_id, list(datapack_ids), packs)
        overrides = map_datapacks(bundle, packs, uses_motion_clip=bool(settings["uses_motion_clip"]))
        if overrides.motion_duration_s is not None:  # a unit of work is one pass through the clip
            settings = {**settings, "unit_duration_s": overrides.motion_duration_s}
        weights, messages = self._overlay(objective, float(settings["overlay_gain"]))
        run_dir = self.run_dir(output_dir, task_id, seed).resolve()
        simulator, device = choose_simulator(self.simulator, self.machine(run_dir))
        plan = plan_training(experiment=settings["experiment"][algo], algo=algo, simulator=simulator, device=device,
                             num_envs=num_envs, max_steps=max_steps, cpu_max_env_steps=self.cpu_max_env_steps)
        messages = [*plan.messages, *overrides.messages, *messages]
        for text in messages:
            progress(f"holosoma: {text}", 1.0, 1.0)
        overlay_params = {k: settings[k] for k in ("progress_mode", "unit_duration_s", "novelty_rate")}
        overlay_params["meter"] = meter_settings(task_id, settings, spec.source, locomotion_where(spec))  # pricing's
        overlay_params["winding_heat_w_per_nm2"] = robot_card(str(settings["robot"]), spec.source).heat_coeff().tolist()
        job = TrainJob(run_dir=str(run_dir), run_name=f"{task_id}-seed{seed}", plan=plan, seed=int(seed),
                       motion_task=bool(settings["uses_motion_clip"]),
                       overlay=Overlay(weights=weights, params=overlay_params), overrides=overrides.to_dict())
        outcome = run_job(self.python, job, run_dir, progress, self.job_timeout_s)
        messages += list(outcome.messages)
        result = outcome.result
        if not result.get("checkpoint") or not result.get("onnx"):
            raise BackendError(f"Holosoma finished without a checkpoint and ONNX export in {result['experiment_dir']}")
        ours = {"task_id": task_id, "objective": objective.to_dict(), "overlay_weights": weights,
                "overlay_gain": settings["overlay_gain"], "task_economics": spec.economics.to_dict(),
                "settings": settings}
        policy_onnx = record_run(run_dir, ours, result, {"simulator": plan.simulator, "algo": algo, "seed": int(seed)},
                                 self.name, self.final_policy_file)
        curve = [{"timesteps": float(c["timesteps"]), "mean_return": float(c["mean_return"])}
                 for c in outcome.curve if c.get("mean_return") is not None]
        config: dict[str, Any] = {
            "seed": seed, "objective": objective.to_dict(), "datapacks": list(bundle.datapack_ids),
            "overrides": overrides.to_dict(), "plan": {**plan.__dict__, "messages": list(plan.messages)},
            "overlay_weights": weights, "messages": messages, **training_log(outcome, result)}
        evaluation = self.evaluate_after_training(run_dir, task_id, objective, eval_episodes, seed,
                                                  datapack_configs=datapack_configs, progress=progress)
        artifacts = {"policy": str(run_dir), "checkpoint": result["checkpoint"], "onnx": str(policy_onnx),
                     "tensorboard": result["experiment_dir"], "train_log": outcome.log_path}
        return self.training_result(run_dir, task_id, evaluation, curve, config, artifacts)

    def evaluate_policy(
        self,
        policy_id: str,
        task_id: str,
        objective: EconomicObjectiveSpec,
        num_episodes: int,
        seed: int,
        *,
        datapack_configs: Sequence[DatapackConfig] | None = None,
        output_dir: str | Path | None = None,
        progress: ProgressFn = no_progress,
        stop: StopFn | None = None,
    ) -> MotorEvalResult:
        """Evaluate a run directory trained here or an imported policy (``policy.onnx``-style file or
        ``holosoma:<robot>/<algo>``); episode ``i`` is seeded ``seed + i``; ``stop`` as the contract's
        (sim-to-sim: every :meth:`evaluation_batch` episodes finished in order).

        Locomotion tasks: the sim-to-sim evaluator (:mod:`econmotor.locomotion.evaluation`) on the
        policy's ONNX, the same for a policy trained here and one trained elsewhere. Whole-body tracking
        (a motion clip): Holosoma's eval_agent with recording, for run directories trained here.
        """
        if num_episodes < 1:
            raise ConfigError("<evaluate>", "num_episodes", f"must be >= 1, got {num_episodes}")
        spec, settings = self._task(task_id)
        imported = is_imported_policy(policy_id)
        self.check_policy(policy_id)
        record = None if imported else read_run_record(policy_id, self.name)
        run_dir = self.run_dir(output_dir, task_id, seed).resolve()
        if settings["progress_mode"] == "velocity":
            policy = str(policy_id) if str(policy_id).startswith(NAME_PREFIX) else \
                str(Path(policy_id if imported else record["onnx"]).resolve())
            return self._sim2sim(policy, str(policy_id), imported, spec, settings, num_episodes, seed,
                                 list(datapack_configs or ()), run_dir, progress, stop)
        if imported:
            raise ConfigError("--policy", str(policy_id), f"task '{task_id}' tracks a motion clip; the sim-to-sim "
                              "evaluator walks locomotion courses",
                              ["humanoid_locomotion_g1", "humanoid_locomotion_t1"])
        return self._eval_agent(record, policy_id, task_id, spec, objective, num_episodes, seed, run_dir, progress)

    def _sim2sim(self, policy: str, policy_id: str, imported: bool, spec: Any, settings: dict[str, Any],
                 num_episodes: int, seed: int, packs: list[DatapackConfig], run_dir: Path,
                 progress: ProgressFn, stop: StopFn | None = None) -> MotorEvalResult:
        """The batched MuJoCo walker env in this interpreter, on :attr:`eval_workers` processes
        (:func:`econmotor.motor_backend.walker_pricing.price_walker`)."""
        return price_walker(WalkerPricing(
            backend=self.name, spec=spec, settings=settings, packs=packs, policy=policy, policy_id=policy_id,
            imported=imported, workers=self.eval_workers, batch=self.evaluation_batch(spec.task_id),
            course_speed_m_per_s=self.course_speed_m_per_s, episode_s=self.eval_episode_length_s,
            fallback_python=self._holosoma_python(), timeout_s=self.job_timeout_s, label="holosoma"),
            num_episodes, seed, run_dir, progress, stop)

    def evaluation_batch(self, task_id: str) -> int:
        """Ten episodes per worker process between looks."""
        return 10 * self.eval_workers

    def _eval_agent(self, record: dict[str, Any], policy_id: str, task_id: str, spec: Any,
                    objective: EconomicObjectiveSpec, num_episodes: int, seed: int, run_dir: Path,
                    progress: ProgressFn) -> MotorEvalResult:
        """Holosoma's eval_agent with recording; econ metrics from the recording's episodes."""
        settings = record["settings"]  # the physical parameters the policy was trained with
        meter = meter_settings(task_id, settings, str(Path(policy_id) / RUN_CONFIG_FILE), "settings")
        episode_s = float(self.eval_episode_length_s or record["episode_length_s"])
        steps = num_episodes * math.ceil(episode_s / float(record["control_dt_s"]))
        simulator = self._eval_simulator(record.get("simulator", "mujoco"), run_dir, progress)
        job = EvaluateJob(run_dir=str(run_dir), checkpoint=record["checkpoint"], num_steps=steps,
                          episode_length_s=episode_s, seed=int(seed), simulator=simulator)
        outcome = run_job(self.python, job, run_dir, progress, self.job_timeout_s)
        raw_episodes = episodes_from_recording(outcome.result["recording"], settings, meter, num_episodes)
        if not raw_episodes:
            raise BackendError(f"Holosoma's recording {outcome.result['recording']} holds no steps")
        config = {"seed": seed, "objective": objective.to_dict(),
                  "recording": outcome.result["recording"], "exported_onnx": outcome.result.get("onnx"),
                  "episode_length_s": episode_s, "num_steps": steps, "messages": list(outcome.messages),
                  "eval_log": outcome.log_path}
        provenance = EvalProvenance(evaluator="eval_agent", figures_from=f"Holosoma's eval_agent on {simulator} "
                                    "(the training checkpoint; econ metrics from its recording)")
        return evaluation_result(self.name, policy_id, task_id, raw_episodes, spec.economics, config,
                                 output_dir=run_dir, provenance=provenance)

    def _eval_simulator(self, trained_on: str, run_dir: Path, progress: ProgressFn) -> str:
        """The training simulator when this machine has it (or the one asked for), else the auto choice."""
        caps = self.machine(run_dir)
        wanted = trained_on if self.simulator == "auto" else self.simulator
        try:
            return choose_simulator(wanted, caps)[0]
        except ConfigError:
            fallback = choose_simulator("auto", caps)[0]
            progress(f"holosoma: evaluating on {fallback}: the policy was trained on {wanted}, "
                     "which this machine cannot run", 1.0, 1.0)
            return fallback

    def deploy_policy_handle(self, policy_id: str) -> OnnxPolicyHandle:
        """An onnxruntime handle for a trained run directory, an ONNX file or a shipped policy name."""
        if str(policy_id).startswith(NAME_PREFIX):
            onnx_path = find_shipped_policy(str(policy_id), self._holosoma_python())
        else:
            path = Path(policy_id)
            onnx_path = path if path.suffix == ".onnx" else Path(read_run_record(policy_id, self.name)["onnx"])
        if not onnx_path.is_file():
            raise BackendError(f"no ONNX policy at {onnx_path}")
        return OnnxPolicyHandle(onnx_path)

    def _holosoma_python(self) -> Path | None:
        """.venv-holosoma's interpreter where there is one (its shipped walkers), else None."""
        try:
            return self.python
        except BackendError:
            return None

    def check_policy(self, policy_id: str) -> None:
        """An imported policy must be a shipped name this .venv-holosoma has or an existing ONNX file; a run
        directory must hold its ``run_config.json`` (ConfigErrors, before any job starts)."""
        if str(policy_id).startswith(NAME_PREFIX):
            find_shipped_policy(str(policy_id), self._holosoma_python())
        elif str(policy_id).endswith(".onnx"):
            if not Path(policy_id).is_file():
                raise ConfigError("--policy", str(policy_id), "no such ONNX file")
        else:
            read_run_record(policy_id, self.name)
