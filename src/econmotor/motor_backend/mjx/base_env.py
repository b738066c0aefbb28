"""One MJX env shape: a single env over a pytree :class:`State` (Brax's ``Env``), and :class:`Wrapper`.

A thin env simulates one env of a task, no batch axis, and nothing but its physics, observation,
task reward and termination: ``reset(key) -> State`` and ``step(state, action) -> State``, pure
JAX functions. Two are named for what they simulate: :class:`~econmotor.motor_backend.mjx.env.GymCourierEnv`
(a Gymnasium v5 body: hopper, walker2d, ant, humanoid) and
:class:`~econmotor.motor_backend.mjx.humanoid_env.HumanoidWalkerEnv` (a robot card: G1, T1). What every
env shares is a wrapper of :mod:`econmotor.motor_backend.mjx.wrappers` (episode bookkeeping, economic
metering, batching, auto-reset), composed by :func:`~econmotor.motor_backend.mjx.wrappers.make_env`.

What a thin env writes into the :class:`State` it returns:

- ``data``, ``obs``; ``reward``: the task reward; ``done``: 1.0 where the step ended in a fall;
  ``truncated``: 1.0 where the env ended the episode itself (the walker's course done);
- ``episode``: its own running sums (the wrappers add theirs), ``info``: its own per-episode state
  (the walker's gait clock and course), ``randomization``: the episode's domain-randomization draws
  (drawn at reset from the reset key, applied each step through :meth:`Env.randomized_model` and the
  env's own noise, gains and pushes);
- ``readings``: what the economic meter reads, one row per metered physics step of the control step
  (:data:`READING_KEYS`; empty when the env is built with ``readings=False``: nothing meters it).

The step's randomness comes from ``state.key``, which the driver (``wrappers.AutoReset``) gives each
step afresh; ``lifelong`` holds what outlives an episode (the meter's novelty table).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import mujoco

from econmotor.motor_backend.mjx._mjx import mjx
from econmotor.motor_backend.mjx.settings import MjxTaskSettings, parse_mjx_settings
from econmotor.tasks import load_catalog

#: one metered physics step (:class:`econmotor.economics.courier_formulas.StepReading`'s physics fields)
READING_KEYS = ("x_m", "mechanical_w", "tilt_rad", "fell", "heat_w")


class State(NamedTuple):
    """One env's state (under :class:`~econmotor.motor_backend.mjx.wrappers.Batch` every array leads with
    ``num_envs``); the fields as the module docstring says."""

    data: Any
    obs: jax.Array
    reward: jax.Array
    done: jax.Array
    truncated: jax.Array
    episode: dict[str, jax.Array]
    finished: dict[str, jax.Array]  # the episode's raw metrics as of this step (an ended one's where ``done``)
    key: jax.Array
    info: dict[str, jax.Array]
    randomization: dict[str, jax.Array]
    readings: dict[str, jax.Array]
    lifelong: dict[str, jax.Array]


#: the fields an auto-reset replaces where an episode ended (the others: the step's outcome, the key, ``lifelong``)
EPISODE_FIELDS = ("data", "obs", "episode", "info", "randomization")


def task_settings(task_id: str, catalog: Any = None) -> tuple[Any, MjxTaskSettings, str]:
    """``(task spec, its validated mjx settings, "<file>: backend_entries.mjx.<task>")`` (the shipped
    catalog unless ``catalog`` is given): what every mjx env starts from."""
    spec = (catalog if catalog is not None else load_catalog()).get(task_id)
    settings = parse_mjx_settings(spec)
    return spec, settings, f"{settings.source}: backend_entries.mjx.{task_id}"


def like(new: Mapping[str, Any], old: Mapping[str, jax.Array]) -> dict[str, jax.Array]:
    """``new`` with ``old``'s dtypes (strong), so a step's carry keeps one type (no recompilation)."""
    return {k: jnp.asarray(v, jnp.asarray(old[k]).dtype) for k, v in new.items()}


def reading(x_m: Any, mechanical_w: Any, tilt_rad: Any, fell: Any, heat_w: Any = 0.0) -> dict[str, jax.Array]:
    """One metered physics step (:data:`READING_KEYS`), typed as every step's (``heat_w``: the windings'
    heat, :func:`~econmotor.economics.courier_formulas.winding_heat_w`; 0 for a body without a motor model)."""
    f32 = jnp.float32
    return {"x_m": jnp.asarray(x_m, f32), "mechanical_w": jnp.asarray(mechanical_w, f32),
            "tilt_rad": jnp.asarray(tilt_rad, f32), "fell": jnp.asarray(fell, bool), "heat_w": jnp.asarray(heat_w, f32)}


class Env:
    """A thin env: one env of an mjx task (module docstring). Subclasses set the attributes below and
    implement :meth:`reset` and :meth:`step`.

    Args:
        task_id: a catalog task with a ``backends.mjx`` entry.
        seed: kept for the caller's records; randomness comes from the keys.
        catalog: a :class:`~econmotor.tasks.TaskCatalog` (default: the shipped one).
        readings: record what the meter reads (False: nothing meters this env).
    """

    #: overlay keys the meter may weight on this env
    terms: tuple[str, ...] = ()
    #: the meter counts visits to cells of the observation's first ``novelty_dims`` (its novelty table)
    counts_novelty = False
    #: raw metrics of a finished episode this env reports besides the meter's (:meth:`extra_metrics`)
    extra_metric_keys: tuple[str, ...] = ()
    #: metered physics steps per control step (rows of ``State.readings``)
    readings_per_step = 1
    #: what steps the physics, in words (run configs, report provenance)
    physics_label = "MJX"

    mj_model: mujoco.MjModel
    action_size: int
    observation_size: int
    control_dt_s: float
    meter_dt_s: float  # the metered step: the control step, or the physics step where every one is metered
    episode_s: float  # the episode's time limit
    max_episode_steps: int

    def __init__(self, task_id: str, *, seed: int = 0, catalog: Any = None, readings: bool = True) -> None:
        self.task_spec, self.settings, self.where = task_settings(task_id, catalog)
        self.task_id, self.seed, self.readings = task_id, int(seed), bool(readings)

    def _use_model(self, mj_model: mujoco.MjModel) -> None:
        """Simulate ``mj_model`` (its MJX copy and an empty data to start episodes from)."""
        self.mj_model = mj_model
        self.model = mjx.put_model(mj_model)
        self._template = mjx.make_data(self.model)

    # ------------------------------------------------------------------ what a thin env implements
    def reset(self, key: jax.Array) -> State:
        """A fresh episode drawn from ``key``."""
        raise NotImplementedError

    def step(self, state: State, action: jax.Array) -> State:
        """One control step (its noise drawn from ``state.key``)."""
        raise NotImplementedError

    def randomized_model(self, draws: Mapping[str, jax.Array]) -> Any:
        """The MJX model an episode with domain-randomization ``draws`` runs (default: the task's)."""
        return self.model

    def extra_metrics(self, state: State) -> dict[str, jax.Array]:
        """:attr:`extra_metric_keys` of the episode in ``state`` (after the meter's sums are in it)."""
        return {}

    # ------------------------------------------------------------------ helpers
    def first_state(self, data: Any, obs: jax.Array, key: jax.Array, *, episode: dict | None = None,
                    info: dict | None = None, randomization: dict | None = None) -> State:
        """A fresh episode's state: no reward, not done, no readings yet."""
        zero = jnp.zeros((), jnp.float32)
        n = self.readings_per_step
        readings = {k: jnp.zeros((n,), v.dtype) for k, v in reading(zero, zero, zero, False).items()} \
            if self.readings else {}
        return State(data, obs, zero, zero, zero, dict(episode or {}), {}, key, dict(info or {}),
                     dict(randomization or {}), readings, {})
