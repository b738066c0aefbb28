"""MjxBackend: the GPU-native motor backend (factory name ``mjx``).

The mujoco couriers (``tasks/mjx.yaml``) simulated by MuJoCo's JAX port in batches
(``wrappers.make_env`` over the thin envs of ``env.py`` and ``humanoid_env.py``, the economics
inside the compiled step), trained by the JAX PPO of ``mjx/ppo.py`` on whatever device JAX sees (GPU when present,
CPU otherwise), evaluated in batches, deployed to ONNX. Same contract, result types, raw-metric
keys, run-directory layout and ConfigError rules as the ``mujoco`` backend, so the registry,
``econmotor report --motor-backend mjx``, ``solve`` and ``sweep`` work unchanged.

On a CPU ``num_envs`` is capped at the task's ``cpu_num_envs_cap`` (64 by default: MJX on a
CPU runs a batch of envs about as fast per env as a few, and compiles slower with more); the
result config records the request, the value used and why (``num_envs_note``).

A new run may start from a walker that exists (``init_policy``: an ONNX file in Holosoma's
format or a shipped name, ``mjx/onnx_import.py``): the actor's weights converted, the network
shaped as the ONNX's, the critic warmed up before the actor moves; ``run_config.json`` (and the
exported ONNX) record ``init_policy``. A task on a real robot (an env with a robot card) exports
in Holosoma's format (``export.py``), so Holosoma's inference stack and the sim-to-sim evaluator
run what was trained here.

XLA compiles each jitted function once per process; a persistent compilation cache (``device.py``,
``compilation_cache_dir``, default ``~/.cache/econmotor/jax``; the CLI passes
``$ECONMOTOR_JAX_CACHE_DIR`` when set, see :attr:`MjxBackend.environment_options`) lets later
processes skip most of it.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any, ClassVar

import jax

from econmotor.config.datapacks import DatapackConfig, DatapackProvider
from econmotor.couriers.onnx_actor import policy_file, read_actor
from econmotor.couriers.policy_import import VENV_ENV
from econmotor.errors import ConfigError
from econmotor.motor_backend.base import MotorBackendBase, ProgressFn, StopFn, no_progress
from econmotor.motor_backend.capabilities import BackendCapabilities, HeldOutCadence, RunSize
from econmotor.motor_backend.mjx import ppo
from econmotor.motor_backend.mjx.compile import CompiledAhead
from econmotor.motor_backend.mjx.device import device_description, enable_compilation_cache
from econmotor.motor_backend.mjx.export import ONNX_FILE, export_run_policy
from econmotor.motor_backend.mjx.onnx_import import check_architecture, warm_start
from econmotor.motor_backend.mjx.settings import MjxTaskSettings, parse_mjx_settings
from econmotor.motor_backend.mjx.training import (
    RUN_CONFIG_FILE,
    MjxTrainingRun,
    evaluate_episodes,
    load_learner,
    read_run_config,
)
from econmotor.motor_backend.onnx_policy import OnnxPolicyHandle
from econmotor.motor_backend.results import (
    EvalProvenance,
    MotorEvalResult,
    MotorTrainingResult,
    aggregate_raw,
    evaluation_result,
    mean_power_w,
    walking_speed_m_per_s,
)
from econmotor.motor_backend.selection import fit_to_run, selection_for
from econmotor.motor_backend.training_loop import CURVE_FILE
from econmotor.objectives.economic_objective import EconomicObjectiveSpec
from econmotor.robots.gym_couriers import robot_name
from econmotor.tasks.catalog import TaskCatalog

CACHE_ENV = "ECONMOTOR_JAX_CACHE_DIR"
#: a run that needs its evaluator within this many iterations (its first held-out evaluation, or its end)
#: compiles it from the start, beside the iteration's compilation; a longer one after its first iteration,
#: beside training: on two cores the two compilations slow each other (the demo's first iteration took
#: 29-35 s with both, 19-21 s alone), while a tiny run would wait for the evaluator after training
COMPILE_AHEAD_ITERATIONS = 8
#: episodes a held-out or report evaluation steps at once on a CPU, by the task's ``cpu_physics``: MJX's step
#: costs in proportion to the batch; a MuJoCo C step called from JAX has ~0.4 ms of fixed cost per batched
#: step (the callback, the meter's small ops), so 48 fall-free hopper episodes cost 1.6x 16 of them, and 96
#: cost 3.3 s instead of 5.2 s (one core); a fast hopper (~1.4 legs an episode) passes at the first look
CPU_EVAL_BATCH = {"mjx": 16, "mujoco": 48}


def env_class(settings: MjxTaskSettings) -> type:
    """The thin env a task's mjx entry asks for: a robot card walking (``robot:``) or a Gymnasium body
    (batched, auto-reset and metered by ``wrappers.make_env``)."""
    from econmotor.motor_backend.mjx.env import GymCourierEnv
    from econmotor.motor_backend.mjx.humanoid_env import HumanoidWalkerEnv

    return HumanoidWalkerEnv if settings.robot is not None else GymCourierEnv


class MjxBackend(MotorBackendBase):
    """Train, evaluate and deploy JAX PPO policies on the MJX couriers.

    Args:
        task_files: extra task catalog YAML files (besides the shipped ones).
        datapack_provider: registered datapacks that ids may refer to.
        keep_task_reward: add the overlay to the task's reward (True) or replace it (False).
        runs_dir: where new run directories go when ``output_dir`` is not given.
        eval_batch: episodes evaluated at once (one compiled batched rollout; None: 256 on an accelerator,
            where a rollout of 1,000 steps costs about the same for 10 envs or 256, and on a CPU, where a step's
            cost grows with the batch, :data:`CPU_EVAL_BATCH`).
        compilation_cache_dir: JAX's persistent compilation cache ("" or None: off).
        holosoma_venv: where shipped policies (``--init-policy holosoma:<robot>/<algo>``) are found when this
            interpreter has no holosoma_inference (default: ``find_holosoma_python``'s search; the CLI passes
            $ECONMOTOR_HOLOSOMA_VENV).
    """

    name = "mjx"
    capabilities = BackendCapabilities(resume=True, algorithms=("ppo",), evaluation_driven=True, init_policies=True,
                                       hyperparameters=True)
    defaults = RunSize(num_envs=0, max_steps=10_000_000)
    # the integration tests' size: 8 envs x unroll 20, so XLA's cache serves every CPU test
    smoke_run = RunSize(num_envs=8, max_steps=320, task_id="hopper_courier")
    max_num_envs = 1 << 20  # one batch on one accelerator; a CPU caps far lower (num_envs_note)
    final_policy_file = "policy.npz"
    checkpoint_glob = "ckpt_*_steps.npz"
    environment_options: ClassVar[Mapping[str, str]] = {CACHE_ENV: "compilation_cache_dir",
                                                        VENV_ENV: "holosoma_venv"}
    #: held-out evaluations after any training iteration once the training since the last took 9 times its
    #: cost: at most 10% of the run's wall time (on a GPU an iteration is ~20k env steps in ~0.07 s)
    held_out_cadence = HeldOutCadence(every_steps=1, max_share=0.10)

    def __init__(self, *, task_files: Sequence[str | Path] = (), runs_dir: str | Path = "runs",
                 catalog: TaskCatalog | None = None,
                 datapack_provider: DatapackProvider | None = None, keep_task_reward: bool = True,
                 eval_batch: int | None = None,
                 compilation_cache_dir: str | Path | None = Path.home() / ".cache" / "econmotor" / "jax",
                 holosoma_venv: str | Path | None = None) -> None:
        if eval_batch is not None and eval_batch < 1:
            raise ConfigError("<mjx backend>", "eval_batch", "must be >= 1")
        super().__init__(task_files=task_files, runs_dir=runs_dir, catalog=catalog)
        self.provider = datapack_provider or DatapackProvider()
        self.keep_task_reward = keep_task_reward
        self.eval_batch = int(eval_batch) if eval_batch else None
        self.compilation_cache_dir = str(compilation_cache_dir) if compilation_cache_dir else None
        self.holosoma_venv = holosoma_venv
        enable_compilation_cache(compilation_cache_dir or None)
        self._envs: dict[str, Any] = {}
        self._evaluators: dict[tuple[int, str], Any] = {}

    @staticmethod
    def device_description() -> str:
        return device_description()

    def num_envs_note(self, task_id: str, num_envs: int) -> str | None:
        """Said when this device runs fewer envs than asked (a CPU caps at the task's ``cpu_num_envs_cap``)."""
        used, note = self.resolve_num_envs(self.settings(task_id), int(num_envs))
        return None if used == num_envs or num_envs <= 0 else f"mjx: {note}"

    @classmethod
    def sweep_resources(cls) -> dict[str, float]:
        """One CPU per cell, and the GPU when JAX trains on one."""
        return {"num_cpus": 1.0, "num_gpus": 1.0 if jax.default_backend() == "gpu" else 0.0}

    @classmethod
    def check_datapack(cls, pack: DatapackConfig, source: str) -> None:
        """The domain randomization the batched couriers honour (no curriculum): the Gymnasium
        couriers' keys, or the humanoid couriers' walker stress keys (``humanoid_stress.yaml``,
        :func:`~econmotor.motor_backend.mjx.humanoid_env.check_humanoid_datapack`)."""
        from econmotor.motor_backend.mjx.env import parse_mjx_randomization
        from econmotor.motor_backend.mjx.humanoid_env import check_humanoid_datapack

        try:
            parse_mjx_randomization([pack])
        except ConfigError as courier_error:
            try:
                check_humanoid_datapack(pack, source)
            except ConfigError:
                raise courier_error from None

    @classmethod
    def robot_id(cls, spec: Any) -> str:
        """The robot card the entry names (``g1_29dof``), else the couriers' robot of its env (``hopper``): the
        ids the holosoma and mujoco backends give the same robots."""
        settings = parse_mjx_settings(spec)
        return settings.robot or robot_name(settings.env_id)

    @classmethod
    def check_task_entry(cls, spec: Any) -> None:
        """The ``backends.mjx`` entry (and with ``inherit: mujoco`` the mujoco entry) as a run reads it."""
        parse_mjx_settings(spec)

    # --- configuration -------------------------------------------------------------------
    def settings(self, task_id: str) -> MjxTaskSettings:
        return parse_mjx_settings(self.catalog.get(task_id))

    def env(self, task_id: str, objective: EconomicObjectiveSpec, datapack_ids: Sequence[str] = (),
            datapack_configs: Sequence[DatapackConfig] | None = None,
            random_start: bool = False) -> tuple[Any, dict[str, Any]]:
        """The (memoised) env for a task, objective and datapacks, and a JSON-able description;
        ``random_start``: a robot card's episodes start at random points of the course (training)."""
        configs = list(datapack_configs or ())
        bundle = self.provider.resolve(task_id, datapack_ids, configs)
        memo = json.dumps([task_id, objective.to_dict(), [p.to_dict() for p in configs], list(bundle.datapack_ids),
                           random_start], sort_keys=True, default=str)
        if memo not in self._envs:
            from econmotor.motor_backend.mjx.wrappers import make_env

            self._envs[memo] = make_env(
                env_class(self.settings(task_id)), task_id, objective=objective,
                datapacks=[bundle] if configs or bundle.datapack_ids else [],
                catalog=self.catalog, keep_task_reward=self.keep_task_reward,
                **({"random_start": True} if random_start else {}))
        env = self._envs[memo]
        spec = self.catalog.get(task_id)
        described = {
            "task_id": task_id, "objective": objective.to_dict(), "overlay": dict(env.scales),
            "overlay_references": dict(env.references), "datapack_ids": list(bundle.datapack_ids),
            "datapacks": [p.to_dict() for p in configs],
            "economics": {r["name"]: r["value"] for r in spec.economics.parameters()},
            "settings": env.settings.to_dict(), "keep_task_reward": self.keep_task_reward,
            "physics": env.physics_label,
        }
        return env, described

    def evaluation_batch(self, task_id: str) -> int:
        """One compiled batched rollout of :attr:`eval_batch` episodes; by default 256 on an accelerator, on a
        CPU :data:`CPU_EVAL_BATCH` of the task's ``cpu_physics``."""
        if self.eval_batch:
            return self.eval_batch
        return CPU_EVAL_BATCH[self.settings(task_id).cpu_physics] if jax.default_backend() == "cpu" else 256

    def _evaluator(self, env: Any, cfg: ppo.PPOConfig, ahead: bool = False) -> Any:
        """The run's one compiled evaluation (memoised per env and hyperparameters); ``ahead``: compile it
        now in a background thread (:class:`CompiledAhead`), overlapping the first training iterations."""
        key = (id(env), json.dumps(cfg.to_dict(), sort_keys=True))
        if key not in self._evaluators:
            jitted = ppo.make_evaluate(env, cfg, self.evaluation_batch(env.task_id))
            if ahead:
                template = ppo.init_learner(jax.random.PRNGKey(0), env.observation_size, env.action_size, cfg)
                jitted = CompiledAhead(jitted, template.params, template.stats, jax.random.PRNGKey(0),
                                       name="econmotor-mjx-evaluate")
            self._evaluators[key] = jitted
        return self._evaluators[key]

    @staticmethod
    def resolve_num_envs(settings: MjxTaskSettings, requested: int) -> tuple[int, str]:
        """``(num_envs, note)``: the request (or the catalog default), capped on a CPU."""
        wanted = requested if requested > 0 else settings.num_envs
        if jax.default_backend() == "cpu" and wanted > settings.cpu_num_envs_cap:
            return settings.cpu_num_envs_cap, (f"{wanted} envs requested; capped at {settings.cpu_num_envs_cap} "
                                               "on a CPU (cpu_num_envs_cap in the task's mjx entry)")
        return wanted, "as requested" if requested > 0 else "the task's default"

    @staticmethod
    def fit_minibatches(cfg: ppo.PPOConfig, num_envs: int, note: str = "",
                        requested: dict[str, Any] | None = None) -> tuple[ppo.PPOConfig, str]:
        """Fewer minibatches when the catalog's do not divide ``num_envs * unroll_length`` (small
        runs, e.g. a sweep's 1 env); an explicitly requested count is left for PPO to reject."""
        batch = num_envs * cfg.unroll_length
        if batch % cfg.num_minibatches == 0 or "num_minibatches" in (requested or {}):
            return cfg, note
        fitted = math.gcd(batch, cfg.num_minibatches)
        note += f"; num_minibatches {cfg.num_minibatches} -> {fitted} (must divide num_envs * unroll_length)"
        return replace(cfg, num_minibatches=fitted), note

    def ppo_config(self, settings: MjxTaskSettings, overrides: dict[str, Any] | None) -> ppo.PPOConfig:
        source = f"{settings.source}: backend_entries.mjx.{settings.task_id}.ppo"
        cfg = ppo.PPOConfig.from_mapping({"normalize_obs": settings.normalize_obs, **settings.ppo}, source)
        return ppo.PPOConfig.from_mapping({**cfg.to_dict(), **overrides}, "<hyperparameters>") if overrides else cfg

    def check_init_policy(self, policy: str, task_id: str) -> None:
        """The ONNX file (or shipped name) exists and its actor is an architecture the mjx actor has."""
        check_architecture(read_actor(policy_file(policy, self.holosoma_venv), policy))

    # --- the MotorBackendBase contract ------------------------------------------------------
    def train_policy(self, task_id: str, objective: EconomicObjectiveSpec, datapack_ids: Sequence[str],
                     num_envs: int, max_steps: int, seed: int, *,
                     datapack_configs: Sequence[DatapackConfig] | None = None,
                     output_dir: str | Path | None = None, eval_episodes: int = 5,
                     progress: ProgressFn = no_progress, resume: bool = False, algorithm: str | None = None,
                     hyperparameters: dict[str, Any] | None = None,
                     checkpoint_every_steps: int | None = None, select_every_steps: int | None = None,
                     select_episodes: int | None = None,
                     until_deployable: bool = False, init_policy: str | None = None) -> MotorTrainingResult:
        """Train with JAX PPO, export ONNX, evaluate ``eval_episodes`` deterministic episodes.

        ``num_envs <= 0``: the catalog's default (capped on a CPU); ``resume=True`` continues the run in
        ``output_dir`` to ``max_steps``; selection and ``until_deployable`` as the mujoco backend's
        (``motor_backend/selection.py``); ``init_policy``: an ONNX file or shipped name (module docstring).
        """
        if algorithm not in (None, "ppo"):
            raise ConfigError("<train>", "algorithm", f"the mjx backend trains PPO only, not '{algorithm}'", ["ppo"])
        if max_steps < 1:
            raise ConfigError("<train>", "max_steps", "must be >= 1")
        settings = self.settings(task_id)
        env, described = self.env(task_id, objective, datapack_ids, datapack_configs)
        # the card robots train from random points of the course (held-out and final evaluations from its start)
        train_env = self.env(task_id, objective, datapack_ids, datapack_configs, random_start=True)[0] \
            if settings.robot is not None else env
        cfg = self.ppo_config(settings, hyperparameters)
        used_envs, note = self.resolve_num_envs(settings, int(num_envs))
        cfg, note = self.fit_minibatches(cfg, used_envs, note, hyperparameters)
        if output_dir is None and resume:
            raise ConfigError("<train>", "output_dir", "resume needs the run directory to continue")
        extra = {"device": device_description(), "num_envs_requested": int(num_envs), "num_envs_note": note}
        if getattr(env, "card", None) is not None:
            extra["robot"] = env.card.name  # exported in Holosoma's format (export.py)
        initial = None
        if init_policy is not None:
            cfg, initial, extra["init_policy"] = self._warm_start(init_policy, resume, env, cfg, hyperparameters,
                                                                  seed, progress)
        batch = self.evaluation_batch(task_id)
        selection = fit_to_run(selection_for(self.catalog.get(task_id), objective, select_every_steps, select_episodes,
                                             until_deployable, seed, self.held_out_cadence, batch), int(max_steps),
                               env.max_episode_steps, eval_episodes, lambda text: progress(f"mjx: {text}", 1.0, 1.0))
        run = MjxTrainingRun(
            run_dir=self.run_dir(output_dir, task_id, seed), env=train_env, described=described, cfg=cfg,
            requested_hyperparameters=hyperparameters, num_envs=used_envs, max_steps=int(max_steps), seed=int(seed),
            checkpoint_every_steps=int(checkpoint_every_steps or settings.checkpoint_every_steps),
            extra_config=extra, initial=initial, selection=selection, cache_dir=self.compilation_cache_dir)
        if run.selection is not None or eval_episodes > 0:
            self._compile_evaluator_ahead(run, env)
        run.held_out = lambda learner, n, first_seed, stop: evaluate_episodes(
            self._evaluator(env, run.cfg), batch, env, learner, n, first_seed, stop=stop)
        run.export = lambda run_dir, learner: export_run_policy(run_dir, learner, run.cfg, run.config)
        curve = run.train(resume=resume, progress=progress)
        config = run.config
        artifacts = {"policy": str(run.run_dir / "policy.npz"), "tensorboard": str(run.run_dir / "tb"),
                     "run_config": str(run.run_dir / RUN_CONFIG_FILE), "onnx": str(run.onnx),
                     "curve": str(run.run_dir / CURVE_FILE)}
        # the same env and compiled evaluator (memoised), the learner train saved as policy.npz
        evaluation = self.evaluate_after_training(run.run_dir, task_id, objective, eval_episodes, seed,
                                                  datapack_configs=datapack_configs, progress=progress,
                                                  datapack_ids=datapack_ids)
        return self.training_result(run.run_dir, task_id, evaluation, curve, config, artifacts)

    def _compile_evaluator_ahead(self, run: MjxTrainingRun, env: Any) -> None:
        """Compile the run's evaluator in the background: from the start when the run needs it within
        :data:`COMPILE_AHEAD_ITERATIONS` iterations, else after its first iteration, beside training (not beside
        the iteration's own compilation, which uses both cores of a small CPU)."""
        every = run.selection.config.every_steps if run.selection is not None else run.max_steps
        if min(every, run.max_steps) <= COMPILE_AHEAD_ITERATIONS * run.num_envs * run.cfg.unroll_length:
            self._evaluator(env, run.cfg, ahead=True)
        else:
            run.after_first_iteration = lambda: self._evaluator(env, run.cfg, ahead=True)

    def _warm_start(self, init_policy: str, resume: bool, env: Any, cfg: ppo.PPOConfig,
                    hyperparameters: dict[str, Any] | None, seed: int,
                    progress: ProgressFn) -> tuple[ppo.PPOConfig, ppo.Learner, dict[str, Any]]:
        """``(cfg, learner, record)`` of a run started from ``init_policy`` (``onnx_import.warm_start``)."""
        if resume:
            raise ConfigError("<train>", "init_policy", "--init-policy starts a new run; --resume continues one "
                              "from its checkpoints (the run records what it started from)")
        actor = read_actor(policy_file(init_policy, self.holosoma_venv), init_policy)
        cfg, initial, notes = warm_start(actor, env, cfg, hyperparameters, seed)
        for text in notes:
            progress(f"mjx: {text}", 1.0, 1.0)
        return cfg, initial, {**actor.describe(), "init_log_std": cfg.init_log_std,
                              "critic_warmup_iterations": cfg.critic_warmup_iterations, "notes": notes}

    def evaluate_policy(self, policy_id: str, task_id: str, objective: EconomicObjectiveSpec, num_episodes: int,
                        seed: int, *, datapack_configs: Sequence[DatapackConfig] | None = None,
                        output_dir: str | Path | None = None, progress: ProgressFn = no_progress,
                        datapack_ids: Sequence[str] = (), stop: StopFn | None = None) -> MotorEvalResult:
        """Run ``num_episodes`` deterministic episodes (``eval_batch`` at a time, keyed by ``seed``);
        ``stop`` as the contract's, after each batch."""
        config = read_run_config(policy_id, task_id)
        env, described = self.env(task_id, objective, datapack_ids, datapack_configs)
        cfg = ppo.PPOConfig.from_mapping(config["hyperparameters"], str(Path(policy_id) / RUN_CONFIG_FILE))
        learner = load_learner(policy_id, config, cfg)
        rows = evaluate_episodes(self._evaluator(env, cfg), self.evaluation_batch(task_id), env, learner,
                                 num_episodes, seed, progress, stop=stop)
        eval_config = {**described, "policy_id": str(policy_id), "num_episodes": num_episodes, "seed": seed,
                       "algorithm": "ppo", "deterministic": True, "device": device_description()}
        provenance = EvalProvenance(
            evaluator="mjx", figures_from=f"batched JAX rollouts of {task_id} (physics: {env.physics_label}) on "
            f"{device_description()} (the run's PPO policy, deterministic, metered as in training)",
            commanded_speed_m_per_s=env.settings.course.get("speed_m_per_s"),
            achieved_speed_m_per_s=walking_speed_m_per_s(rows), mean_power_w=mean_power_w(aggregate_raw(rows)))
        return evaluation_result(self.name, policy_id, task_id, rows, self.catalog.get(task_id).economics,
                                 eval_config, output_dir, provenance)

    def deploy_policy_handle(self, policy_id: str) -> OnnxPolicyHandle:
        """An onnxruntime handle on the run's ``policy.onnx`` (exported now if missing)."""
        path = Path(policy_id) / ONNX_FILE
        config = read_run_config(policy_id)  # an mjx run directory, checked before anything is loaded
        if not path.is_file():
            cfg = ppo.PPOConfig.from_mapping(config["hyperparameters"], str(Path(policy_id) / RUN_CONFIG_FILE))
            export_run_policy(Path(policy_id), load_learner(policy_id, config, cfg), cfg, config)
        return OnnxPolicyHandle(path)
