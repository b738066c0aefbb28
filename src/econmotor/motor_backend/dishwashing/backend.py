"""The ``dishwashing`` motor backend: SB3 SAC on the analytic dishwashing workcell.

Training reward is the compiled objective overlay (``DishwashingEnv(reward_mode="overlay")``)
with each term divided by a reference (``overlay_normalization``):

- ``"human_baseline"`` (default): every metric is a rate over the time worked, divided by
  what a robot working at the human pace would score: ``mpl_per_hour / MP_h``,
  ``error_rate / e_h``, energy as ``energy_kwh_per_hour / E_h`` with
  ``E_h = MP_h/(1 - e_h) * energy_Wh_per_attempt / 1000`` kWh/h, ``risk_score / 1``.
  The objective's ``energy_weight`` is moved from ``energy_kwh`` (kWh per episode) to
  ``energy_kwh_per_hour`` (:func:`training_objective`): episode kWh grows with episode
  length while MPL and error rate do not, so with it the cheapest way to save energy is to
  end the shift early (e.g. by violating the SLA), which is not what anyone asking for an
  energy saver means. A weight of 1 then means "one human baseline's worth" of that
  metric, so a preset's weights compare like with like; without normalisation the MPL
  term (tens of units/h) dwarfs the error rate (hundredths) and the energy (thousandths
  of a kWh), and every preset trains the same policy.
- ``"none"``: the objective as given, raw terms, exactly ``sum_k scale_k * term_k``.

The whole reward is multiplied by ``SACSettings.reward_scale`` for SAC's sake (it does not
change the optimum). ``policy_id`` is the run directory (``output_dir``): it holds the
saved ``policy.zip`` and ``run_config.json``, everything needed to reproduce the run.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from econmotor.config.datapacks import DatapackConfig, DatapackProvider
from econmotor.config.econ_params import ECON_PRESETS, EconParams, econ_params_with
from econmotor.config.loading import as_str, check_keys, require_mapping
from econmotor.config.task_economics import TaskEconomics
from econmotor.envs.dishwashing import DishwashingEnv
from econmotor.envs.dishwashing_randomization import EconRandomization, parse_econ_randomization
from econmotor.errors import BackendError, ConfigError
from econmotor.motor_backend.base import MotorBackendBase, ProgressFn, StepAlias, StopFn, no_progress
from econmotor.motor_backend.capabilities import BackendCapabilities, RunSize, ShadowEnv
from econmotor.motor_backend.results import (
    EvalProvenance,
    MotorEvalResult,
    MotorTrainingResult,
    aggregate_raw,
    evaluation_result,
    mean_power_w,
)
from econmotor.motor_backend.run_dir import RUN_CONFIG_FILE, read_run_config
from econmotor.motor_backend.training_loop import CURVE_FILE, TrainingLoop
from econmotor.objectives.economic_objective import EconomicObjectiveSpec
from econmotor.tasks.catalog import TaskCatalog, TaskSpec

BACKEND_NAME = "dishwashing"
#: the registry's robot id of the analytic workcell every dishwashing task runs
ROBOT_ID = "dishwashing_workcell"
OVERLAY_NORMALIZATIONS = ("human_baseline", "none")
_TASK_ENTRY_KEYS = ("econ_preset", "econ_overrides", "overlay_normalization")


@dataclass(frozen=True)
class SACSettings:
    """SAC hyperparameters (SB3 names). Defaults train 2,000 steps in ~10 s on one core.

    ``reward_scale`` multiplies the environment reward before SAC sees it;
    ``net_arch`` is the hidden layer sizes of actor and critics; ``curve_every_steps`` the
    spacing of training-curve points. ``gamma = 0.95``: the workcell's optimum is nearly
    myopic (an action's effect on MPL, errors and energy shows up in the same step) and a
    short horizon cut the variance enough that 20k steps on 4 envs reach MPL 97.5 units/h
    under ``throughput`` against 83 with ``gamma = 0.99, learning_rate = 1e-3`` on 1 env
    (10k steps), the analytic constant-action optimum being ~98.
    """

    learning_rate: float = 3e-3
    buffer_size: int = 100_000
    learning_starts: int = 200
    batch_size: int = 128
    tau: float = 0.02
    gamma: float = 0.95
    train_freq: int = 1
    gradient_steps: int = 1
    ent_coef: str | float = "auto"
    net_arch: tuple[int, ...] = (64, 64)
    reward_scale: float = 10.0
    curve_every_steps: int = 500


class SACPolicyHandle(StepAlias):
    """A deployed SAC policy: ``act(obs)`` (or ``step(obs)``) -> deterministic (speed, care)."""

    def __init__(self, model: Any, policy_id: str) -> None:
        self.model, self.policy_id = model, policy_id
        self.obs_dim = int(np.prod(model.observation_space.shape))

    def act(self, obs: np.ndarray) -> np.ndarray:
        action, _ = self.model.predict(np.asarray(obs, dtype=np.float32), deterministic=True)
        return action


def term_references(params: EconParams, economics: TaskEconomics) -> dict[str, float]:
    """The ``human_baseline`` references (see the module docstring), one per overlay key.

    ``energy_kwh`` (used only with an objective that keeps it, e.g. one that already weights
    ``energy_kwh_per_hour``) is referenced to one full episode at the human pace.
    """
    attempts_per_h = economics.mp_human_units_per_hour / max(1e-9, 1.0 - economics.error_rate_human)
    kwh_per_h = max(attempts_per_h * params.energy_Wh_per_attempt / 1000.0, 1e-12)
    return {
        "mpl_per_hour": economics.mp_human_units_per_hour,
        "error_rate": max(economics.error_rate_human, 1e-6),
        "energy_kwh_per_hour": kwh_per_h,
        "energy_kwh": kwh_per_h * params.max_steps * params.time_step_s / 3600.0,
        "risk_score": 1.0,
        "novelty_score": 1.0,
    }


def training_objective(objective: EconomicObjectiveSpec, normalization: str) -> EconomicObjectiveSpec:
    """The objective the env is trained on: under ``human_baseline`` energy is per hour worked.

    ``energy_weight`` becomes ``extra_weights["energy_kwh_per_hour"] = -|energy_weight|``
    (see the module docstring); everything else is unchanged. ``"none"`` returns it as given.
    """
    if normalization == "none" or objective.energy_weight == 0 or "energy_kwh_per_hour" in objective.extra_weights:
        return objective
    extras = {**objective.extra_weights, "energy_kwh_per_hour": -abs(objective.energy_weight)}
    return replace(objective, energy_weight=0.0, extra_weights=extras)


class DishwashingBackend(MotorBackendBase):
    """Train, evaluate and deploy SAC policies on the dishwashing workcell.

    Args:
        sac: SAC hyperparameters.
        overlay_normalization: ``"human_baseline"`` or ``"none"``; a task's catalog entry
            may set its own (``backends: {dishwashing: {overlay_normalization: none}}``).
        known_datapacks: datapacks that ``datapack_ids`` may name without passing configs.
        task_files: extra task catalog YAML files.
        runs_dir: where new run directories go when ``output_dir`` is not given.
        torch_threads: torch CPU threads (1 is fastest for these small networks).
    """

    name = BACKEND_NAME
    capabilities = BackendCapabilities(shadow_env=True)
    defaults = RunSize(num_envs=1, max_steps=5_000)
    smoke_run = RunSize(num_envs=1, max_steps=300, task_id="dishwashing")
    max_num_envs = 256  # in-process DummyVecEnv
    final_policy_file = "policy.zip"

    def __init__(
        self,
        *,
        task_files: Sequence[str | Path] = (),
        runs_dir: str | Path = "runs",
        catalog: TaskCatalog | None = None,
        sac: SACSettings | None = None,
        overlay_normalization: str = "human_baseline",
        known_datapacks: Sequence[DatapackConfig] = (),
        torch_threads: int = 1,
    ) -> None:
        if overlay_normalization not in OVERLAY_NORMALIZATIONS:
            raise ConfigError("<dishwashing backend>", "overlay_normalization",
                              f"unknown {overlay_normalization!r}", OVERLAY_NORMALIZATIONS)
        super().__init__(task_files=task_files, runs_dir=runs_dir, catalog=catalog)
        self.sac = sac or SACSettings()
        self.overlay_normalization = overlay_normalization
        self.datapacks = DatapackProvider(known_datapacks)
        self.torch_threads = int(torch_threads)

    @classmethod
    def check_datapack(cls, pack: DatapackConfig, source: str) -> None:
        """The EconParams randomization and curriculum a dishwashing run would apply."""
        parse_econ_randomization(pack.domain_randomization, pack.curriculum, source)

    @classmethod
    def robot_id(cls, spec: TaskSpec) -> str:
        """Every dishwashing task runs the one analytic workcell (a cobot arm and gripper at a dish station)."""
        return ROBOT_ID

    @classmethod
    def check_task_entry(cls, spec: TaskSpec) -> None:
        """The task entry's keys, EconParams preset and overrides, and overlay normalization."""
        cls._entry_params(spec)

    # ----------------------------------------------------------- task set-up
    @staticmethod
    def _entry_params(spec: TaskSpec) -> tuple[EconParams, str | None]:
        """(EconParams, overlay normalization or None) of ``spec``'s entry, validated."""
        entry = spec.backend_entry(BACKEND_NAME)
        source, key = spec.source, f"tasks.{spec.task_id}.backends.{BACKEND_NAME}"
        check_keys(entry, _TASK_ENTRY_KEYS, source, key)
        preset = as_str(entry.get("econ_preset", "toy"), source, f"{key}.econ_preset", ECON_PRESETS)
        overrides = require_mapping(entry["econ_overrides"], source, f"{key}.econ_overrides") \
            if entry.get("econ_overrides") else {}
        params = econ_params_with(EconParams.preset(preset), overrides, source, f"{key}.econ_overrides")
        norm = entry.get("overlay_normalization")
        if norm is not None:
            as_str(norm, source, f"{key}.overlay_normalization", OVERLAY_NORMALIZATIONS)
        return params, norm

    @classmethod
    def shadow_env(cls, spec: TaskSpec, max_episode_steps: int | None = None,
                   econ_overrides: Mapping[str, Any] | None = None) -> ShadowEnv:
        """The workcell on the legacy reward (``info["step_summary"]`` every step), with the entry's
        EconParams and ``econ_overrides`` on top (flag ``--econ-override``)."""
        params, _ = cls._entry_params(spec)
        if econ_overrides:
            params = params.with_overrides(dict(econ_overrides), source="--econ-override")
        env = DishwashingEnv(params, reward_mode="legacy", max_steps=max_episode_steps)
        return ShadowEnv(env, params.time_step_s, env.max_steps)

    def _task(self, task_id: str) -> tuple[TaskSpec, EconParams, str]:
        spec = self.catalog.get(task_id)
        params, norm = self._entry_params(spec)
        return spec, params, norm or self.overlay_normalization

    def _randomization(self, task_id: str, ids: Sequence[str], configs: Sequence[Any] | None) -> EconRandomization:
        bundle = self.datapacks.resolve(task_id, list(ids), list(configs or ()))
        source = ", ".join(bundle.sources.values()) or "<datapacks>"
        return parse_econ_randomization(bundle.domain_randomization, bundle.curriculum, source)

    def _env_factory(self, spec: TaskSpec, params: EconParams, norm: str, objective: EconomicObjectiveSpec,
                     randomization: EconRandomization) -> Callable[[], DishwashingEnv]:
        refs = term_references(params, spec.economics) if norm == "human_baseline" else {}
        rand = randomization if randomization.ranges else None
        trained_on = training_objective(objective, norm)

        def make() -> DishwashingEnv:
            return DishwashingEnv(params, "overlay", objective=trained_on, randomization=rand, term_references=refs)

        return make

    # ------------------------------------------------------------- training
    def _model(self, make: Callable[[], gym.Env], num_envs: int, max_steps: int, seed: int) -> Any:
        """SAC on ``num_envs`` envs of ``make`` (rewards times the SAC settings' scale, SB3 ``DummyVecEnv``)."""
        from stable_baselines3 import SAC
        from stable_baselines3.common.monitor import Monitor
        from stable_baselines3.common.vec_env import DummyVecEnv

        hp = self.sac
        build = lambda: Monitor(gym.wrappers.TransformReward(make(), lambda r: r * hp.reward_scale))
        vec = DummyVecEnv([build for _ in range(num_envs)])
        vec.seed(seed)
        return SAC(
            "MlpPolicy", vec, seed=seed, device="cpu", verbose=0,
            learning_rate=hp.learning_rate, buffer_size=min(hp.buffer_size, max(max_steps, 1000)),
            learning_starts=min(hp.learning_starts, max_steps // 2), batch_size=hp.batch_size, tau=hp.tau,
            gamma=hp.gamma, train_freq=hp.train_freq, gradient_steps=hp.gradient_steps, ent_coef=hp.ent_coef,
            policy_kwargs={"net_arch": list(hp.net_arch)},
        )

    def _described(self, spec: TaskSpec, params: EconParams, norm: str, objective: EconomicObjectiveSpec,
                   randomization: EconRandomization, make: Callable[[], gym.Env]) -> dict[str, Any]:
        """What the run's config records of the learner, the workcell and the overlay."""
        return {"sac": asdict(self.sac), "torch_threads": self.torch_threads, "econ_params": params.to_dict(),
                "overlay_normalization": norm,
                "term_references": term_references(params, spec.economics) if norm != "none" else {},
                "training_objective": training_objective(objective, norm).to_dict(),
                "overlay_keys_ignored": list(make().ignored_overlay_keys), "randomization": randomization.to_dict()}

    def train_policy(
        self,
        task_id: str,
        objective: EconomicObjectiveSpec,
        datapack_ids: Sequence[str],
        num_envs: int,
        max_steps: int,
        seed: int,
        *,
        datapack_configs: Sequence[Any] | None = None,
        output_dir: str | Path | None = None,
        eval_episodes: int = 5,
        progress: ProgressFn = no_progress,
    ) -> MotorTrainingResult:
        """Train SAC for ``max_steps`` environment steps (summed over ``num_envs``), save, evaluate.

        Args:
            task_id: a catalog task with a ``dishwashing`` entry.
            objective: compiled into the overlay reward.
            datapack_ids / datapack_configs: domain randomization and curriculum of EconParams.
            num_envs / max_steps: environments stepped together (SB3 ``DummyVecEnv``); total env steps.
            seed: seeds SAC, torch and the environments.
            output_dir: the run directory (default: a new one under ``runs_dir``); it must not hold a run.
            eval_episodes / progress: deterministic episodes after training; ``progress(label, done, total)``.
        """
        import torch

        if num_envs < 1 or max_steps < 1:
            raise ConfigError("<train>", "num_envs" if num_envs < 1 else "max_steps", "must be >= 1")
        run_dir = self.run_dir(output_dir, task_id, seed)
        if (run_dir / RUN_CONFIG_FILE).exists():
            raise ConfigError(str(run_dir), None, "already holds a run; choose a new output directory")
        spec, params, norm = self._task(task_id)
        randomization = self._randomization(task_id, datapack_ids, datapack_configs)
        make = self._env_factory(spec, params, norm, objective, randomization)
        torch.set_num_threads(self.torch_threads)
        config = {"task_id": task_id, "objective": objective.to_dict(), "datapack_ids": list(datapack_ids),
                  "datapack_configs": [c.to_dict() for c in (datapack_configs or ()) if hasattr(c, "to_dict")],
                  "num_envs": num_envs, "seed": seed, "eval_episodes": eval_episodes,
                  **self._described(spec, params, norm, objective, randomization, make)}
        from econmotor.motor_backend.dishwashing.learner import SACLearner

        loop = TrainingLoop(run_dir, self.name, config, max_steps, curve_every_steps=self.sac.curve_every_steps,
                            progress=progress, label=f"train {task_id}")
        try:
            outcome = loop.run(SACLearner(self._model(make, num_envs, max_steps, seed)))
        except (ValueError, RuntimeError) as exc:
            raise BackendError(f"SAC training on '{task_id}' failed: {exc}") from exc
        config, curve = outcome.config, outcome.curve
        evaluation = self.evaluate_after_training(run_dir, task_id, objective, eval_episodes, seed,
                                                  datapack_configs=datapack_configs, progress=progress,
                                                  datapack_ids=datapack_ids)
        return self.training_result(run_dir, task_id, evaluation, curve, config,
                                    {"policy": str(run_dir / self.final_policy_file),
                                     "run_config": str(run_dir / RUN_CONFIG_FILE), "curve": str(run_dir / CURVE_FILE)})

    # ----------------------------------------------------------- evaluation
    def _evaluate(self, model: Any, spec: TaskSpec, params: EconParams, norm: str,
                  objective: EconomicObjectiveSpec, randomization: EconRandomization, num_episodes: int,
                  seed: int, progress: ProgressFn, stop: StopFn | None = None) -> list[dict[str, Any]]:
        """Raw episodes at the curriculum's final difficulty: the task as it will be met."""
        rand = replace(randomization, initial_difficulty=randomization.max_difficulty)
        env = self._env_factory(spec, params, norm, objective, rand)()
        handle = SACPolicyHandle(model, "")
        raw_episodes = []
        progress("evaluate", 0, num_episodes)
        for i in range(num_episodes):
            if stop is not None and i and i % self.evaluation_batch(spec.task_id) == 0 and stop(raw_episodes):
                break
            obs, _ = env.reset(seed=seed + i)
            done = False
            while not done:
                obs, _, term, trunc, info = env.step(handle.act(obs))
                done = term or trunc
            raw_episodes.append(info["episode_summary"])
            progress("evaluate", i + 1, num_episodes)
        return raw_episodes

    def evaluate_policy(
        self,
        policy_id: str,
        task_id: str,
        objective: EconomicObjectiveSpec,
        num_episodes: int,
        seed: int,
        *,
        datapack_configs: Sequence[Any] | None = None,
        output_dir: str | Path | None = None,
        progress: ProgressFn = no_progress,
        stop: StopFn | None = None,
        datapack_ids: Sequence[str] = (),
    ) -> MotorEvalResult:
        """Run ``num_episodes`` deterministic episodes (seeds ``seed + i``) of a saved policy; ``stop`` as
        the contract's.

        ``return`` in each episode is the reward the policy is trained on (normalised as the
        backend says, without ``reward_scale``); with ``output_dir``, the evaluation is also written
        there (``evaluation.json``, as every backend writes it). ``datapack_ids``: registered datapacks
        applied beside ``datapack_configs``.
        """
        if num_episodes < 1:
            raise ConfigError("<evaluate>", "num_episodes", "must be >= 1")
        spec, params, norm = self._task(task_id)
        randomization = self._randomization(task_id, datapack_ids, datapack_configs)
        model = self.deploy_policy_handle(policy_id).model
        raw_episodes = self._evaluate(model, spec, params, norm, objective, randomization, num_episodes, seed,
                                      progress, stop)
        config = {"backend": BACKEND_NAME, "task_id": task_id, "objective": objective.to_dict(),
                  "num_episodes": num_episodes, "seed": seed, "overlay_normalization": norm}
        provenance = EvalProvenance(evaluator="analytic", figures_from="the analytic dishwashing workcell "
                                    "(econmotor's Gymnasium model of the cell; the saved SAC policy, deterministic)",
                                    mean_power_w=mean_power_w(aggregate_raw(raw_episodes)))
        return evaluation_result(BACKEND_NAME, policy_id, task_id, raw_episodes, spec.economics, config, output_dir,
                                 provenance)

    def deploy_policy_handle(self, policy_id: str) -> SACPolicyHandle:
        """Load the run directory's ``policy.zip`` (or a ``policy.zip`` path); a missing or unreadable
        file is a BackendError."""
        import torch
        from stable_baselines3 import SAC

        path = Path(policy_id)
        if path.is_dir():
            read_run_config(path, self.name)  # a run directory: this backend's
            path = path / self.final_policy_file
        if not path.is_file():
            raise BackendError(f"no saved dishwashing policy at '{policy_id}': pass the policy_id (the run "
                               f"directory holding {self.final_policy_file}) that train_policy returned")
        torch.set_num_threads(self.torch_threads)
        try:
            model = SAC.load(path, device="cpu")
        except Exception as exc:  # SB3 raises many types for a bad zip
            raise BackendError(f"cannot load SAC policy '{policy_id}': {exc}") from exc
        return SACPolicyHandle(model, str(path))
