"""The base environment of a shadow run: the dishwashing workcell or a metered MuJoCo task.

:func:`make_task_env` returns a :class:`TaskEnv`: the env (whose ``info`` carries a
``step_summary`` every step and an episode summary on the last), the task's
economics from the catalog (what every J is computed with, see
``econmotor.valuation.episode_j``), the seconds per step, the episode length limit and
the task id.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import gymnasium as gym

from econmotor.config.econ_params import load_econ_params
from econmotor.config.task_economics import TaskEconomics
from econmotor.errors import ConfigError
from econmotor.tasks import load_catalog

DISHWASHING_BACKEND = "dishwashing"


@dataclass
class TaskEnv:
    """A built base env and what shadow mode needs to know about it.

    Attributes:
        env: the Gymnasium env (``info["step_summary"]`` every step).
        economics: the task economics from the catalog (the same object ``econmotor solve``
            prices a recorded episode with).
        dt_s: seconds per env step.
        max_episode_steps: episode length limit, steps.
        task_id: the catalog id.
    """

    env: gym.Env
    economics: TaskEconomics
    dt_s: float
    max_episode_steps: int
    task_id: str = ""


def make_task_env(task_id: str, max_episode_steps: int | None = None,
                  econ_overrides: Mapping[str, Any] | None = None) -> TaskEnv:
    """Build ``task_id``: a catalog task with a ``dishwashing`` entry, else one with a ``mujoco`` entry.

    Args:
        task_id: ``dishwashing``, ``dishwashing_realistic`` or a MuJoCo task id (``hopper_courier``...).
        max_episode_steps: override of the episode length (dishwashing only; MuJoCo keeps its TimeLimit).
        econ_overrides: EconParams fields to override (dishwashing only).
    """
    spec = load_catalog().get(task_id)
    if DISHWASHING_BACKEND in spec.backends:
        from econmotor.envs.dishwashing import DishwashingEnv

        entry = spec.backend_entry(DISHWASHING_BACKEND)
        params = load_econ_params(str(entry.get("econ_preset", "toy")))
        if econ_overrides:
            params = params.with_overrides(dict(econ_overrides), source="--econ-override")
        env = DishwashingEnv(params, reward_mode="legacy", max_steps=max_episode_steps)
        return TaskEnv(env, spec.economics, params.time_step_s, env.max_steps, task_id)
    if "mujoco" not in spec.backends:
        raise ConfigError("--env", task_id, "the task has neither a dishwashing nor a mujoco backend entry",
                          ["dishwashing", "mujoco"])
    if econ_overrides:
        raise ConfigError("--env", task_id, "EconParams overrides apply to dishwashing tasks only")
    from econmotor.motor_backend.mujoco.metering import EconomicMeteringWrapper
    from econmotor.motor_backend.mujoco.settings import parse_mujoco_settings
    from econmotor.rl.step_summary import MujocoStepSummaryWrapper

    settings = parse_mujoco_settings(spec)
    kwargs = dict(settings.env_kwargs)
    if max_episode_steps is not None:
        kwargs["max_episode_steps"] = int(max_episode_steps)
    env = gym.make(settings.env_id, **kwargs)
    env = EconomicMeteringWrapper(env, leg_distance_m=settings.leg_distance_m,
                                  drivetrain_efficiency=settings.drivetrain_efficiency,
                                  idle_power_w=settings.idle_power_w, tilt_margin_rad=settings.tilt_margin_rad,
                                  fall_tilt_rad=settings.fall_tilt_rad, novelty_dims=settings.novelty_dims,
                                  novelty_bin=settings.novelty_bin)
    env = MujocoStepSummaryWrapper(env, spec.economics)
    limit = env.spec.max_episode_steps if env.spec is not None and env.spec.max_episode_steps else 1000
    return TaskEnv(env, spec.economics, float(env.unwrapped.dt), int(limit), task_id)
