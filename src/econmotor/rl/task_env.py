"""The base environment of a shadow run: the dishwashing workcell or a metered MuJoCo task, built by
the backend that declares it can (the contract's ``shadow_env``).

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

from econmotor.config.task_economics import TaskEconomics
from econmotor.errors import ConfigError
from econmotor.motor_backend.factory import backend_class, known_backends
from econmotor.tasks import load_catalog
from econmotor.tasks.catalog import TaskSpec


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
    """Build ``task_id`` through the first of its backends that builds a single Gymnasium env
    (``capabilities.shadow_env``: ``dishwashing`` and ``mujoco`` today).

    Args:
        task_id: ``dishwashing``, ``dishwashing_realistic`` or a MuJoCo task id (``hopper_courier``...).
        max_episode_steps: override of the episode length (where the backend allows it).
        econ_overrides: the backend's economic parameters to override (dishwashing's EconParams).
    """
    spec = load_catalog().get(task_id)
    env, dt_s, limit = backend_class(shadow_backend(spec)).shadow_env(spec, max_episode_steps, econ_overrides)
    return TaskEnv(env, spec.economics, float(dt_s), int(limit), task_id)


def shadow_backend(spec: TaskSpec) -> str:
    """The first of ``spec``'s backends that builds a single Gymnasium env; a ConfigError names the
    backends that can where none of the task's can."""
    for name in spec.backends:
        if backend_class(name).capabilities.shadow_env:
            return name
    offering = [name for name in known_backends() if backend_class(name).capabilities.shadow_env]
    raise ConfigError("--env", spec.task_id, "none of the task's backends builds a single Gymnasium env "
                      f"(its backends: {', '.join(spec.backends)})", offering)
