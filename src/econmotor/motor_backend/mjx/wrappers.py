"""The wrappers every MJX env shares, and :func:`make_env`, the batched env the learner steps.

As Brax's ``wrap_for_training`` (``EpisodeWrapper``, then ``VmapWrapper``, then ``AutoResetWrapper``)::

    AutoReset(Batch(EconomicMeter(Episode(thin env))))      # economics=False: without EconomicMeter

- :class:`Episode`: control steps, the task return, the time limit (``truncated``), ``done``, and the raw
  metrics every env reports (``length_steps``, ``return``, ``fell``).
- :class:`EconomicMeter`: the economics inside the step, one implementation for every env. Each reading of
  the thin env (``State.readings``: one per metered physics step) goes through
  :func:`econmotor.economics.courier_formulas.meter_step` (units on the forward high-water mark of x;
  energy ``sum |qfrc_actuator * qvel|`` / drivetrain efficiency + idle power; a fall is one error, the
  readings after it unmetered; tilt risk; novelty ``1 / sqrt(n)`` visits where the env counts it), and the
  reward becomes ``keep_task_reward * r_task + J(t) - J(t-1)``, ``J = sum_k scale_k / ref_k * m_k`` over the
  running episode metrics ``m_k`` (the compiled :class:`EconomicObjectiveSpec`): each term's episode sum is
  the episode metric of its key, as in ``couriers/overlay.py``. :meth:`EconomicMeter.finished_to_dicts`:
  finished episodes as the mujoco backend's raw-episode dicts.
- :class:`Batch`: ``vmap`` over ``num_envs``.
- :class:`AutoReset`: the batched API (``reset(key, num_envs)``, ``step(state, action)``) and the key stream;
  where an episode ends, ``finished`` holds its raw metrics, ``done``/``truncated`` say how it ended, and
  ``data``/``obs``/``episode``/``info``/``randomization`` are already the next episode's (as Brax's
  AutoResetWrapper, but with a fresh random start per episode, computed only when some episode ended).

Novelty: the ``mujoco`` backend counts visits per cell in an unbounded dict per env; here each env has a
fixed table of ``novelty_table_size`` counters indexed by a hash of the cell, kept across episodes, so two
cells that hash alike share a count (with a few hundred cells visited per env and 4,096 slots, collisions
are rare but possible: novelty can read a little lower than on the CPU).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from econmotor.couriers.overlay import human_baseline_references, overlay_term_factors
from econmotor.economics import courier_formulas as cf
from econmotor.economics.termination import TerminationReason
from econmotor.motor_backend.mjx.base_env import EPISODE_FIELDS, Env, State, like
from econmotor.objectives.economic_objective import EconomicObjectiveSpec, compile_economic_overlay

#: the meter's running sums kept in ``State.episode``
METER_KEYS = tuple(f.name for f in dataclasses.fields(cf.MeterSums))
#: raw metrics every env reports (:class:`Episode`)
EPISODE_METRIC_KEYS = ("length_steps", "return", "fell")
#: raw metrics of a metered episode before the env's own and the overlay terms
BASE_METRIC_KEYS = ("units_completed", "units_attempted", "errors", "episode_length_s", "length_steps", "energy_wh",
                    "risk_score", "novelty_score", "return", "forward_distance_m", "fell", "overlay_return")
#: raw metrics that are flags, not columns of a raw-episode dict (they give its ``termination_reason``)
FLAG_KEYS = ("fell", "course_done")
_HASH_PRIMES = (73856093, 19349663, 83492791, 2654435761, 40503, 2246822519, 3266489917, 668265263)


class Wrapper:
    """An env around an env: what it does not define (attributes, methods) is the inner env's."""

    def __init__(self, env: Any) -> None:
        self.env = env

    def __getattr__(self, name: str) -> Any:
        if name.startswith("__") or name == "env":
            raise AttributeError(name)
        return getattr(self.env, name)

    @property
    def unwrapped(self) -> Env:
        """The thin env inside."""
        return self.env.unwrapped if isinstance(self.env, Wrapper) else self.env


class Episode(Wrapper):
    """Control steps, the task return, the time limit and ``done`` (Brax's EpisodeWrapper); an env without
    the meter reports ``length_steps``, ``return`` and ``fell`` only, and its reward is the task's."""

    economics = False
    scales: Mapping[str, float] = {}
    references: Mapping[str, float] = {}
    factors: Mapping[str, float] = {}
    metric_keys = EPISODE_METRIC_KEYS

    def reset(self, key: jax.Array) -> State:
        state = self.env.reset(key)
        zero = jnp.zeros((), jnp.float32)
        episode = {"control_steps": zero, "task_return": zero, **state.episode}  # the env may start the clock later
        return state._replace(episode=episode, finished={**state.finished, **dict.fromkeys(EPISODE_METRIC_KEYS, zero)})

    def step(self, state: State, action: jax.Array) -> State:
        nxt = self.env.step(state, action)
        ep = {**nxt.episode, "control_steps": nxt.episode["control_steps"] + 1.0,
              "task_return": nxt.episode["task_return"] + nxt.reward}
        fell = nxt.done > 0
        truncated = ((ep["control_steps"] >= self.max_episode_steps) | (nxt.truncated > 0)) & ~fell
        finished = {**nxt.finished, "length_steps": ep["control_steps"], "return": ep["task_return"],
                    "fell": fell.astype(jnp.float32)}
        return nxt._replace(episode=like(ep, state.episode), done=(fell | truncated).astype(jnp.float32),
                            truncated=truncated.astype(jnp.float32), finished=like(finished, state.finished))

    def finished_to_dicts(self, finished: Mapping[str, Any]) -> list[dict[str, Any]]:
        raise ValueError("an env built with economics=False has no raw economic metrics")


def novelty_visit(counts: jax.Array, point: jax.Array, novelty_bin: float) -> tuple[jax.Array, jax.Array]:
    """``(counts, bonus)``: the visit of ``point``'s cell counted in the hashed table ``counts``."""
    cell = cf.novelty_cell(point, novelty_bin, jnp).astype(jnp.int32).astype(jnp.uint32)
    primes = jnp.asarray(np.array(_HASH_PRIMES[: cell.shape[0]] + (1,) * max(0, cell.shape[0] - 8), dtype=np.uint32))
    h = jnp.bitwise_xor.reduce(cell * primes) % jnp.uint32(counts.shape[0])
    counts = counts.at[h].add(1)
    return counts, cf.novelty_bonus(counts[h].astype(jnp.float32))


def with_overlay_columns(row: dict[str, Any], cols: Mapping[str, np.ndarray], i: int,
                         factors: Mapping[str, float]) -> dict[str, Any]:
    """A finished episode's row with ``total_return`` and each overlay term's ``overlay_<key>_raw``
    (episode ``i`` of ``cols``) and ``overlay_<key>_weighted`` (times its factor)."""
    row["total_return"] = row["return"] + row["overlay_return"]
    for k, factor in factors.items():
        raw = float(cols[f"overlay_{k}_raw"][i])
        row[f"overlay_{k}_raw"] = raw
        row[f"overlay_{k}_weighted"] = factor * raw
    return row


class EconomicMeter(Wrapper):
    """The economics inside the step (module docstring), over an :class:`Episode`.

    Args:
        env: an :class:`Episode` around a thin env built with ``readings=True``.
        objective: the economic objective compiled into the reward overlay (None: no overlay).
        keep_task_reward: add the overlay to the task reward (True) or use it alone.
    """

    economics = True

    def __init__(self, env: Episode, objective: EconomicObjectiveSpec | None = None,
                 keep_task_reward: bool = True) -> None:
        super().__init__(env)
        s, econ = env.settings, env.task_spec.economics
        self.keep_task_reward = bool(keep_task_reward)
        # the overlay: scales and human-baseline references as the mujoco backend compiles them
        self.scales = dict(compile_economic_overlay(objective)) if objective is not None else {}
        refs = human_baseline_references(econ.mp_human_units_per_hour, econ.error_rate_human, s.idle_power_w,
                                         env.episode_s) if s.overlay_normalization == "human_baseline" else {}
        self.references = {k: v for k, v in refs.items() if k in self.scales}
        # scale_k / ref_k; a term this env cannot weight is a ConfigError
        self.factors = overlay_term_factors(self.scales, self.references, terms=env.terms, backend="mjx")
        self.constants = cf.MeterConstants(s.leg_distance_m, s.drivetrain_efficiency, s.idle_power_w, env.meter_dt_s,
                                           s.tilt_margin_rad, s.fall_tilt_rad)
        self.coefficients = cf.overlay_coefficients(self.factors, env.meter_dt_s)
        self.metric_keys = BASE_METRIC_KEYS + tuple(env.extra_metric_keys) + \
            tuple(f"overlay_{k}_raw" for k in self.scales)

    def reset(self, key: jax.Array) -> State:
        state = self.env.reset(key)
        zero = jnp.zeros((), jnp.float32)
        x0 = state.data.qpos[0]
        episode = {**dict.fromkeys(METER_KEYS, zero), "overlay_j": zero, **state.episode, "best_x": x0, "x0": x0}
        lifelong = {**state.lifelong, "novelty_counts": jnp.zeros((self.settings.novelty_table_size,), jnp.int32)} \
            if self.counts_novelty else state.lifelong
        finished = {**state.finished, **dict.fromkeys(self.metric_keys, zero)}
        return state._replace(episode=episode, finished=finished, lifelong=lifelong)

    def _meter(self, ep: Mapping[str, jax.Array], readings: Mapping[str, jax.Array],
               novelty_bonus: Any) -> cf.MeterSums:
        """The episode's sums after this step's readings (those after a fall unmetered); the step's novelty
        bonus rides on its first reading."""
        sums = cf.MeterSums(**{k: ep[k] for k in METER_KEYS})
        alive = None
        for i in range(readings["fell"].shape[0]):
            before = dataclasses.replace(sums)
            fell = readings["fell"][i]
            cf.meter_step(sums, cf.StepReading(readings["x_m"][i], readings["mechanical_w"][i], readings["tilt_rad"][i],
                                               fell, novelty_bonus if i == 0 else 0.0,
                                               heat_w=readings["heat_w"][i]), self.constants, jnp)
            if alive is not None:  # the first reading counts always; a later one while the robot is up
                for k in METER_KEYS:
                    setattr(sums, k, jnp.where(alive, getattr(sums, k), getattr(before, k)))
            alive = ~fell if alive is None else alive & ~fell
        return sums

    def step(self, state: State, action: jax.Array) -> State:
        nxt = self.env.step(state, action)
        ep, lifelong, bonus = nxt.episode, nxt.lifelong, 0.0
        if self.counts_novelty:
            counts, bonus = novelty_visit(lifelong["novelty_counts"], nxt.obs[: self.settings.novelty_dims],
                                          self.settings.novelty_bin)
            lifelong = {**lifelong, "novelty_counts": counts}
        sums = self._meter(ep, nxt.readings, bonus)
        j = jnp.asarray(cf.overlay_potential(sums, self.coefficients, jnp), jnp.float32)
        ep = like({**ep, **{k: getattr(sums, k) for k in METER_KEYS}, "overlay_j": j}, state.episode)
        reward = (nxt.reward if self.keep_task_reward else 0.0) + (j - state.episode["overlay_j"])
        nxt = nxt._replace(episode=ep, reward=jnp.asarray(reward, jnp.float32), lifelong=lifelong)
        return nxt._replace(finished=like({**nxt.finished, **self._episode_metrics(nxt)}, state.finished))

    def _episode_metrics(self, state: State) -> dict[str, jax.Array]:
        """The meter's raw metrics of the episode in ``state``, the env's own and each overlay term's."""
        ep = state.episode
        metrics = cf.running_metrics(cf.MeterSums(**{k: ep[k] for k in METER_KEYS}), self.meter_dt_s, jnp)
        out = {
            "units_completed": ep["units"], "units_attempted": ep["units"] + ep["errors"], "errors": ep["errors"],
            "episode_length_s": ep["steps"] * self.meter_dt_s, "energy_wh": ep["energy_wh"],
            "risk_score": metrics.risk_score, "novelty_score": metrics.novelty_score,
            "forward_distance_m": ep["best_x"] - ep["x0"], "overlay_return": ep["overlay_j"],
            **self.unwrapped.extra_metrics(state),
        }
        for k in self.scales:
            out[f"overlay_{k}_raw"] = getattr(metrics, k)
        return out

    def finished_to_dicts(self, finished: Mapping[str, Any]) -> list[dict[str, Any]]:
        """Rows of finished episodes (arrays of one length) -> the mujoco backend's raw-episode dicts.

        Keys and types as ``mujoco/evaluation.py``'s ``flatten_episode`` (the walkers': the sim-to-sim
        evaluator's): the raw metrics, ``control_dt_s``, ``termination_reason``, ``overlay_return``,
        ``total_return`` and ``overlay_<key>_raw`` / ``overlay_<key>_weighted``.
        """
        cols = {k: np.asarray(v, dtype=np.float64).reshape(-1) for k, v in finished.items()}
        columns = [k for k in BASE_METRIC_KEYS + tuple(self.extra_metric_keys) if k not in FLAG_KEYS]
        rows = []
        for i in range(len(cols["fell"]) if cols else 0):
            row = {k: float(cols[k][i]) for k in columns}
            row["control_dt_s"] = self.control_dt_s
            row["termination_reason"] = TerminationReason.FALL if cols["fell"][i] > 0.5 else \
                TerminationReason.COURSE_DONE if "course_done" in cols and cols["course_done"][i] > 0.5 else \
                TerminationReason.MAX_STEPS
            rows.append(with_overlay_columns(row, cols, i, self.factors))
        return rows


class Batch(Wrapper):
    """``num_envs`` envs at once (``vmap``; every array of the state leads with ``num_envs``)."""

    def reset(self, keys: jax.Array) -> State:
        return jax.vmap(self.env.reset)(keys)

    def step(self, state: State, action: jax.Array) -> State:
        return jax.vmap(self.env.step)(state, action)


def auto_reset(done: jax.Array, reset: Any, reset_keys: jax.Array, carry: Any) -> Any:
    """``carry`` (a pytree of per-env arrays) with the envs where ``done`` replaced by the same fields of
    ``reset(reset_keys)``, which is computed only when some episode ended."""
    def reset_done(c: Any) -> Any:
        fresh = reset(reset_keys)
        fresh = {k: getattr(fresh, k) for k in c} if isinstance(c, dict) else fresh

        def pick(new: jax.Array, old: jax.Array) -> jax.Array:
            return jnp.where(done.reshape(done.shape + (1,) * (old.ndim - 1)), new, old)

        return jax.tree_util.tree_map(pick, fresh, c)

    return jax.lax.cond(jnp.any(done), reset_done, lambda c: c, carry)


class AutoReset(Wrapper):
    """The batched env the learner steps (pure ``reset(key, num_envs)`` and ``step(state, action)``; jit
    ``reset`` with ``num_envs`` static): each env's key stream, and a fresh episode where one ended."""

    def reset(self, key: jax.Array, num_envs: int) -> State:
        """``num_envs`` fresh episodes."""
        keys = jax.random.split(key, 2 * num_envs)
        return self.env.reset(keys[num_envs:])._replace(key=keys[:num_envs])

    def step(self, state: State, action: jax.Array) -> State:
        """One control step of every env, auto-resetting the ones whose episode ended."""
        keys = jax.vmap(lambda k: jax.random.split(k, 3))(state.key)
        env_keys, step_keys, reset_keys = keys[:, 0], keys[:, 1], keys[:, 2]
        nxt = self.env.step(state._replace(key=step_keys), action)
        fresh = auto_reset(nxt.done > 0, self.env.reset, reset_keys, {f: getattr(nxt, f) for f in EPISODE_FIELDS})
        return nxt._replace(key=env_keys, **fresh)


def make_env(env_class: type[Env], task_id: str, *, objective: EconomicObjectiveSpec | None = None,
             datapacks: Sequence[Any] = (), seed: int = 0, catalog: Any = None, keep_task_reward: bool = True,
             economics: bool = True, **env_options: Any) -> AutoReset:
    """The batched env of ``task_id`` on the thin env ``env_class`` (module docstring).

    Args:
        env_class: :class:`~econmotor.motor_backend.mjx.env.GymCourierEnv` or
            :class:`~econmotor.motor_backend.mjx.humanoid_env.HumanoidWalkerEnv`.
        task_id, datapacks, seed, catalog, env_options: the thin env's.
        objective, keep_task_reward: the :class:`EconomicMeter`'s.
        economics: False leaves the meter out (the reward is the task's, ``finished`` holds only the
            return, length and fall): the baseline ``benchmarks/mjx_throughput.py`` times the economics against.
    """
    thin = env_class(task_id, datapacks=datapacks, seed=seed, catalog=catalog, readings=economics, **env_options)
    env: Wrapper = Episode(thin)
    if economics:
        env = EconomicMeter(env, objective, keep_task_reward)
    return AutoReset(Batch(env))
