"""Build the wrapped MuJoCo environments the backend trains and evaluates on.

Wrapper order, inside out::

    gymnasium.make(env_id)            # TimeLimit inside
    -> PoseTrackingWrapper            # when motion clips are given (RSI + info["pose_tracking"])
    -> DomainRandomizationWrapper     # when domain randomization is given
    -> EconomicMeteringWrapper        # units, energy, falls, risk, novelty; with the overlay:
                                      #   task reward + sum scale_k * term_k (one wrapper, one call per step)
    -> stable_baselines3 Monitor      # episode returns for logging (vector envs only)
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import gymnasium as gym

from econmotor.motor_backend.mujoco.clips import MotionClip, PoseTrackingWrapper
from econmotor.motor_backend.mujoco.metering import EconomicMeteringWrapper
from econmotor.motor_backend.mujoco.randomization import (
    Curriculum,
    DomainRandomization,
    DomainRandomizationWrapper,
    make_base_env,
)
from econmotor.motor_backend.mujoco.settings import MujocoTaskSettings


@dataclass(frozen=True, eq=False)
class EnvRecipe:
    """Everything needed to build one wrapped env, picklable for subprocess vector envs."""

    settings: MujocoTaskSettings
    scales: Mapping[str, float] = field(default_factory=dict)
    references: Mapping[str, float] = field(default_factory=dict)
    keep_task_reward: bool = True
    randomization: DomainRandomization = field(default_factory=DomainRandomization)
    curriculum: Curriculum = field(default_factory=Curriculum)
    clips: tuple[MotionClip, ...] = ()
    reference_init: bool = True
    difficulty: float | None = None  # None: the curriculum's difficulty at step 0

    def start_difficulty(self) -> float:
        return self.curriculum.difficulty(0) if self.difficulty is None else self.difficulty


def make_env(recipe: EnvRecipe, seed: int | None = None, overlay: bool = True, training: bool = False) -> gym.Env:
    """One wrapped env (order in the module docstring); ``overlay=False``: the meter alone (the task's
    reward). ``training``: an env to train on, metering novelty only where the overlay rewards it
    (an evaluation's env meters every term)."""
    s = recipe.settings
    env = make_base_env(s.env_id, s.env_kwargs, recipe.randomization)
    if recipe.clips:
        env = PoseTrackingWrapper(env, recipe.clips, recipe.reference_init, seed=seed)
    if recipe.randomization.active:
        env = DomainRandomizationWrapper(env, recipe.randomization, recipe.start_difficulty(), seed=seed)
    return EconomicMeteringWrapper(env, s.leg_distance_m, s.drivetrain_efficiency, s.idle_power_w,
                                   s.tilt_margin_rad, s.fall_tilt_rad, s.novelty_dims, s.novelty_bin,
                                   scales=recipe.scales if overlay else None,
                                   keep_task_reward=recipe.keep_task_reward, references=recipe.references,
                                   meter_novelty=not training)


def env_builder(recipe: EnvRecipe, seed: int) -> Callable[[], gym.Env]:
    """A thunk building one monitored env to train on (for DummyVecEnv / SubprocVecEnv)."""

    def build() -> gym.Env:
        from stable_baselines3.common.monitor import Monitor

        return Monitor(make_env(recipe, seed, training=True), info_keywords=())

    return build


def make_vec_env(recipe: EnvRecipe, num_envs: int, seed: int, vec_env: str = "dummy") -> Any:
    """``num_envs`` monitored envs in-process (``"dummy"``, the default on small machines) or in
    subprocesses (``"subproc"``), seeded ``seed + i``."""
    from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv

    thunks = [env_builder(recipe, seed + i) for i in range(num_envs)]
    venv = SubprocVecEnv(thunks) if vec_env == "subproc" else DummyVecEnv(thunks)
    venv.seed(seed)
    return venv
