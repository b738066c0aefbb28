"""MujocoBackend: the embedded default motor backend (factory name ``mujoco``).

Gymnasium MuJoCo tasks (Hopper-v5, Walker2d-v5, Ant-v5, Humanoid-v5, ... as listed in the
task catalog's ``backends.mujoco`` entries, see ``tasks/mujoco.yaml``) trained with
Stable-Baselines3 PPO or SAC on the CPU. The reward is the task's own reward plus the
compiled economic overlay (``couriers/overlay.py``); the physics is metered into the raw
metrics :class:`~econmotor.economics.EconomicMeter` reads (``mujoco/metering.py``);
datapacks add domain randomization, a curriculum and motion clips (``mujoco/randomization.py``,
``mujoco/clips.py``); policies deploy to ONNX (``mujoco/export.py``).

``policy_id`` is the run directory (layout in ``mujoco/training.py``).

The card robots (G1, T1: tasks whose ``backends.mujoco`` entry holds ``walker:``) train on the CPU
with PPO on the batched MuJoCo walker env that prices them, from scratch or ``--init-policy`` (a
Holosoma-format ONNX), export Holosoma's ONNX format and are priced sim-to-sim on the same env
(``mujoco/walker_backend.py``, ``mujoco/walker_training.py``, ``mujoco/walker_ppo.py``).
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import gymnasium as gym
import torch

from econmotor.config.datapacks import DatapackConfig, DatapackProvider
from econmotor.couriers.datapack_mapping import map_datapacks
from econmotor.couriers.onnx_actor import policy_file, read_actor
from econmotor.couriers.overlay import human_baseline_references
from econmotor.errors import BackendError, ConfigError
from econmotor.motor_backend.base import MotorBackendBase, ProgressFn, StopFn, no_progress
from econmotor.motor_backend.capabilities import BackendCapabilities, RunSize, ShadowEnv
from econmotor.motor_backend.mujoco.clips import check_clip_file, load_bundle_clips, record_clip
from econmotor.motor_backend.mujoco.env_factory import EnvRecipe
from econmotor.motor_backend.mujoco.evaluation import load_policy
from econmotor.motor_backend.mujoco.export import OnnxPolicyHandle, export_onnx
from econmotor.motor_backend.mujoco.metering import EconomicMeteringWrapper
from econmotor.motor_backend.mujoco.randomization import parse_randomization
from econmotor.motor_backend.mujoco.settings import MujocoTaskSettings, parse_mujoco_settings
from econmotor.motor_backend.mujoco.step_summary import MujocoStepSummaryWrapper
from econmotor.motor_backend.mujoco.task_kinds import TaskKind, run_kind, task_kind
from econmotor.motor_backend.mujoco.training import obs_normalizer
from econmotor.motor_backend.results import MotorEvalResult, MotorTrainingResult
from econmotor.motor_backend.run_dir import RUN_CONFIG_FILE, read_run_config
from econmotor.objectives.economic_objective import EconomicObjectiveSpec, compile_economic_overlay
from econmotor.tasks.catalog import TaskCatalog, TaskSpec

ONNX_FILE = "policy.onnx"


class MujocoBackend(MotorBackendBase):
    """Train, evaluate and deploy SB3 policies on Gymnasium MuJoCo tasks.

    Args:
        task_files: extra task catalog YAML files (besides the shipped ones).
        datapack_provider: registered datapacks that ids may refer to.
        vec_env: ``"dummy"`` (in-process, the default: fastest on 2 cores) or ``"subproc"``.
        keep_task_reward: add the overlay to the task's reward (True) or replace it (False).
        runs_dir: where new run directories go when ``output_dir`` is not given.
        torch_threads: torch intra-op threads while training / evaluating (1: small MLPs run
            fastest single-threaded, and parallel jobs do not oversubscribe the cores).
    """

    name = "mujoco"
    capabilities = BackendCapabilities(resume=True, algorithms=("ppo", "sac"), vec_env_kinds=("dummy", "subproc"),
                                       records_clips=True, evaluation_driven=True, shadow_env=True,
                                       init_policies=True, time_budget=True, hyperparameters=True)
    defaults = RunSize(num_envs=0, max_steps=100_000)
    smoke_run = RunSize(num_envs=1, max_steps=1024, task_id="hopper_courier")  # two PPO rollouts of 512
    max_num_envs = 256  # SB3 vector envs: one process (subproc) or one env object (dummy) each
    final_policy_file = "policy.zip"
    # SB3's checkpoints, and the card robots' walker trainer's one (walker_training.CHECKPOINT_FILE)
    checkpoint_glob = ("*.zip", "latest.pt")

    def __init__(self, *, task_files: Sequence[str | Path] = (), runs_dir: str | Path = "runs",
                 catalog: TaskCatalog | None = None,
                 datapack_provider: DatapackProvider | None = None, vec_env: str = "dummy",
                 keep_task_reward: bool = True, torch_threads: int = 1, eval_workers: int | None = None) -> None:
        if vec_env not in self.capabilities.vec_env_kinds:
            raise ConfigError("<mujoco backend>", "vec_env", f"unknown vector env '{vec_env}'",
                              self.capabilities.vec_env_kinds)
        super().__init__(task_files=task_files, runs_dir=runs_dir, catalog=catalog)
        self.provider = datapack_provider or DatapackProvider()
        self.vec_env = vec_env
        self.keep_task_reward = keep_task_reward
        self.torch_threads = max(1, int(torch_threads))
        #: worker processes of a walker task's sim-to-sim evaluation (None: the CPUs this process may use)
        self.eval_workers = int(eval_workers or (len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity")
                                                 else os.cpu_count() or 1))

    # --- configuration -------------------------------------------------------------------
    def task(self, task_id: str) -> tuple[TaskSpec, MujocoTaskSettings]:
        """The catalog entry and its validated mujoco settings; unknown ids list the known ones."""
        spec = self.catalog.get(task_id)
        return spec, parse_mujoco_settings(spec)

    def recipe(self, task_id: str, objective: EconomicObjectiveSpec, datapack_ids: Sequence[str] = (),
               datapack_configs: Sequence[DatapackConfig] | None = None) -> tuple[EnvRecipe, dict[str, Any]]:
        """The env recipe for a task, objective and datapacks, and a JSON-able description of it."""
        spec, settings = self.task(task_id)
        configs = list(datapack_configs or ())
        for pack in configs:  # validate each pack alone first, so errors name the right file
            parse_randomization(pack.domain_randomization, pack.curriculum, f"{pack.source} (datapack '{pack.id}')")
        bundle = self.provider.resolve(task_id, datapack_ids, configs)
        randomization, curriculum = parse_randomization(bundle.domain_randomization, bundle.curriculum,
                                                        ", ".join(bundle.sources.values()) or "<datapacks>")
        probe = gym.make(settings.env_id, **settings.env_kwargs)
        nq, max_episode_s = probe.unwrapped.model.nq, (probe.spec.max_episode_steps or 1000) * probe.unwrapped.dt
        probe.close()
        clips = tuple(load_bundle_clips(bundle, nq)) if bundle.motion_clips else ()
        scales = dict(compile_economic_overlay(objective))
        if clips and "pose_tracking" not in scales:
            scales["pose_tracking"] = settings.pose_tracking_scale
        econ = spec.economics
        refs = human_baseline_references(econ.mp_human_units_per_hour, econ.error_rate_human, settings.idle_power_w,
                                         max_episode_s) if settings.overlay_normalization == "human_baseline" else {}
        refs = {k: v for k, v in refs.items() if k in scales}
        recipe = EnvRecipe(settings, scales, refs, self.keep_task_reward, randomization, curriculum, clips)
        described = {
            "task_id": task_id, "objective": objective.to_dict(), "overlay": scales, "overlay_references": refs,
            "datapack_ids": list(bundle.datapack_ids),
            "datapacks": [p.to_dict() for p in configs],
            "economics": {r["name"]: r["value"] for r in spec.economics.parameters()},
            "settings": settings.to_dict(), "keep_task_reward": self.keep_task_reward,
        }
        return recipe, described

    def kind(self, task_id: str) -> TaskKind:
        """What the task is to this backend (:func:`task_kind`, the one place it is declared)."""
        return task_kind(self.catalog.get(task_id))

    def evaluation_batch(self, task_id: str) -> int:
        """Held-out episodes run :data:`HELD_OUT_BATCH` envs at a time; a report's evaluation asks ``stop``
        as often (a walker task: ten episodes per worker process, as the holosoma backend's)."""
        return self.kind(task_id).evaluation_batch(self)

    # --- the MotorBackendBase contract ------------------------------------------------------
    def train_policy(self, task_id: str, objective: EconomicObjectiveSpec, datapack_ids: Sequence[str],
                     num_envs: int, max_steps: int, seed: int, *,
                     datapack_configs: Sequence[DatapackConfig] | None = None,
                     output_dir: str | Path | None = None, eval_episodes: int = 5,
                     progress: ProgressFn = no_progress, resume: bool = False, algorithm: str | None = None,
                     hyperparameters: dict[str, Any] | None = None,
                     checkpoint_every_steps: int | None = None, select_every_steps: int | None = None,
                     select_episodes: int | None = None,
                     until_deployable: bool = False, init_policy: str | None = None,
                     max_wall_s: float | None = None) -> MotorTrainingResult:
        """Train a policy and evaluate it on ``eval_episodes`` deterministic episodes.

        ``num_envs <= 0`` uses the catalog's default; ``resume=True`` continues the run in
        ``output_dir`` from its newest checkpoint up to ``max_steps`` total environment steps.
        Evaluation-driven training (``motor_backend/selection.py``): every ``select_every_steps``
        env steps (None: :attr:`held_out_cadence`) and at the end, a sequential held-out evaluation of
        at most ``select_episodes`` episodes judges the policy by the task's acceptance rule; the best is
        kept (``0`` turns it off: the last weights are kept).
        ``until_deployable`` stops at the first held-out evaluation that passes. ``max_wall_s`` stops
        training at a wall-time budget (walker tasks). A walker task (the G1, T1) trains on the batched
        walker env, from ``init_policy`` (an ONNX walker) or from scratch (module docstring).
        """
        torch.set_num_threads(self.torch_threads)
        spec = self.catalog.get(task_id)
        kind = task_kind(spec)
        if not kind.starts_from_policies and (init_policy is not None or max_wall_s is not None):
            raise ConfigError("--init-policy/--max-minutes", task_id, "apply to the card robots' walker tasks only",
                              self._tasks_starting_from_policies())
        return kind.train(self, spec, objective=objective, datapack_ids=datapack_ids,
                          datapack_configs=list(datapack_configs or ()), num_envs=num_envs, max_steps=max_steps,
                          seed=seed, output_dir=output_dir, eval_episodes=eval_episodes, progress=progress,
                          resume=resume, algorithm=algorithm, hyperparameters=hyperparameters,
                          checkpoint_every_steps=checkpoint_every_steps, select_every_steps=select_every_steps,
                          select_episodes=select_episodes, until_deployable=until_deployable,
                          init_policy=init_policy, max_wall_s=max_wall_s)

    def evaluate_policy(self, policy_id: str, task_id: str, objective: EconomicObjectiveSpec, num_episodes: int,
                        seed: int, *, datapack_configs: Sequence[DatapackConfig] | None = None,
                        output_dir: str | Path | None = None, progress: ProgressFn = no_progress,
                        datapack_ids: Sequence[str] = (), stop: StopFn | None = None) -> MotorEvalResult:
        """Run ``num_episodes`` deterministic episodes (episode i seeded ``seed + i``); ``stop`` as the
        contract's (asked every :meth:`evaluation_batch` episodes).

        Datapacks given here (e.g. randomization) apply at full difficulty; without them the
        nominal task is evaluated.
        """
        config = read_run_config(policy_id, "mujoco", task_id)
        return self.kind(task_id).evaluate(self, policy_id, self.catalog.get(task_id), objective=objective,
                                           num_episodes=num_episodes, seed=seed, config=config,
                                           datapack_configs=list(datapack_configs or ()), output_dir=output_dir,
                                           progress=progress, datapack_ids=datapack_ids, stop=stop)

    def deploy_policy_handle(self, policy_id: str) -> OnnxPolicyHandle:
        """An onnxruntime handle on the run's ``policy.onnx`` (exported now if missing)."""
        path = Path(policy_id) / ONNX_FILE
        config = read_run_config(policy_id, self.name)  # a mujoco run directory, checked before anything is loaded
        if not path.is_file() and not run_kind(config).exports_on_demand:
            raise BackendError(f"{run_kind(config).name} run {policy_id} has no {ONNX_FILE}: it did not finish "
                               "(resume it)")
        if not path.is_file():
            model, _ = load_policy(policy_id, config["algorithm"])
            export_onnx(model, obs_normalizer(policy_id), path, self.onnx_metadata(config))
        return OnnxPolicyHandle(path)

    # --- declarations ----------------------------------------------------------------------------
    @classmethod
    def shadow_env(cls, spec: TaskSpec, max_episode_steps: int | None = None,
                   econ_overrides: Mapping[str, Any] | None = None) -> ShadowEnv:
        """The task's Gymnasium env metered like training (:class:`EconomicMeteringWrapper`) with
        ``info["step_summary"]`` every step (:class:`MujocoStepSummaryWrapper`); no EconParams."""
        if econ_overrides:
            raise ConfigError("--env", spec.task_id, "EconParams overrides apply to dishwashing tasks only")
        settings = parse_mujoco_settings(spec)
        kwargs = dict(settings.env_kwargs)
        if max_episode_steps is not None:
            kwargs["max_episode_steps"] = int(max_episode_steps)
        env = EconomicMeteringWrapper(gym.make(settings.env_id, **kwargs), leg_distance_m=settings.leg_distance_m,
                                      drivetrain_efficiency=settings.drivetrain_efficiency,
                                      idle_power_w=settings.idle_power_w, tilt_margin_rad=settings.tilt_margin_rad,
                                      fall_tilt_rad=settings.fall_tilt_rad, novelty_dims=settings.novelty_dims,
                                      novelty_bin=settings.novelty_bin)
        env = MujocoStepSummaryWrapper(env, spec.economics)
        limit = env.spec.max_episode_steps if env.spec is not None and env.spec.max_episode_steps else 1000
        return ShadowEnv(env, float(env.unwrapped.dt), int(limit))

    @classmethod
    def robot_id(cls, spec: TaskSpec) -> str:
        """The couriers' robot of the task's env (``Hopper-v5`` -> ``hopper``); a walker task's robot card."""
        return task_kind(spec).robot_id(spec)

    @classmethod
    def check_datapack(cls, pack: DatapackConfig, source: str) -> None:
        """The randomization and curriculum a mujoco training run would apply, and its motion clips'
        files (their frames are checked against the robot when a run loads them); or the stress a walker
        task (the G1, T1) trains and is priced under."""
        try:
            parse_randomization(pack.domain_randomization, pack.curriculum, source)
        except ConfigError as sb3_error:
            try:
                bundle = DatapackProvider().resolve("<validate>", [pack.id], [pack])
                map_datapacks(bundle, [pack], uses_motion_clip=False)
            except ConfigError:
                raise sb3_error from None
        for i, clip in enumerate(pack.motion_clips):
            check_clip_file(clip.resolve(pack.base_dir), source, f"motion_clips[{i}]")

    @classmethod
    def check_task_entry(cls, spec: TaskSpec) -> None:
        """The ``backends.mujoco`` entry as a training run reads it (``parse_mujoco_settings``; a walker task's
        trainer settings and walker entry)."""
        task_kind(spec).check_entry(spec)

    def check_init_policy(self, policy: str, task_id: str) -> None:
        """``--init-policy`` starts the walker tasks only, from an ONNX actor this trainer can read."""
        if not self.kind(task_id).starts_from_policies:
            raise ConfigError("--init-policy", policy, f"task '{task_id}' trains with SB3 from scratch; the mujoco "
                              "backend starts the card robots' walker tasks from a policy",
                              self._tasks_starting_from_policies())
        read_actor(policy_file(policy), policy)

    def _tasks_starting_from_policies(self) -> list[str]:
        return [t for t in self.catalog.ids(self.name) if self.kind(t).starts_from_policies]

    @classmethod
    def is_complete_run(cls, run_dir: str | Path) -> bool:
        """An SB3 run's ``policy.zip`` or a walker run's ``policy.onnx``, beside its ``run_config.json``."""
        folder = Path(run_dir)
        if not (folder / RUN_CONFIG_FILE).is_file():
            return False
        return (folder / run_kind(read_run_config(folder)).final_policy_file).is_file()

    # --- extras ------------------------------------------------------------------------------
    def record_clip(self, policy_id: str, path: str | Path, num_steps: int = 500, seed: int = 0) -> Path:
        """Roll the policy out deterministically and save the visited poses as a motion clip npz."""
        config = read_run_config(policy_id, "mujoco")
        _, settings = self.task(config["task_id"])
        _, act = load_policy(policy_id, config["algorithm"])
        env = gym.make(settings.env_id, **settings.env_kwargs)
        try:
            return record_clip(env, act, num_steps, seed, path)
        finally:
            env.close()

    @staticmethod
    def eval_recipe(recipe: EnvRecipe) -> EnvRecipe:
        """Evaluation uses the datapacks at full difficulty and the env's default initial state."""
        from dataclasses import replace

        return replace(recipe, difficulty=recipe.curriculum.max_difficulty, reference_init=False)

    @staticmethod
    def onnx_metadata(config: dict[str, Any]) -> dict[str, Any]:
        if "task_id" not in config:
            raise BackendError("run config has no task_id; cannot describe the ONNX policy")
        keys = ("task_id", "overlay", "overlay_references", "objective", "datapack_ids", "economics",
                "algorithm", "obs_layout", "action_layout", "seed")
        return {key: config.get(key) for key in keys}
