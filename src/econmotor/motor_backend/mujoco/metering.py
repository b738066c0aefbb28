"""EconomicMeteringWrapper: read the economics of a MuJoCo rollout from the physics, add the overlay.

Per control step (duration ``dt = frame_skip * timestep`` s), from ``env.unwrapped.data``:

- units: a *delivery leg* is ``leg_distance_m`` of forward (+x) travel of the root.
  Progress is a high-water mark, so moving back and forth earns nothing:
  ``units_t = (max_{s<=t} x_s - x_0) / leg_distance_m`` (fractional legs).
- electrical energy, Wh: mechanical power ``P_mech = sum_j |qfrc_actuator_j * qvel_j|`` W over the
  degrees of freedom (``qfrc_actuator`` is the actuator force *after* the gear; unactuated
  dofs read 0, so the sum runs over :func:`actuated_dof_span` only), electrical
  ``P_el = P_mech / drivetrain_efficiency + idle_power_w``,
  ``energy_wh += P_el * dt / 3600``. Power is sampled at the end of each control step.
- falls: the env's own unhealthy termination (``terminated=True``) is one fall = one error.
- risk in [0, 1]: ``clip((tilt - tilt_margin_rad) / (fall_tilt_rad - tilt_margin_rad), 0, 1)``,
  tilt = the torso's angle from upright (planar robots: the root hinge; free-floating robots:
  from the root quaternion, ``cos(tilt) = 1 - 2 (qx^2 + qy^2)``).
- novelty: ``1 / sqrt(n(s))`` where ``n`` counts visits (kept across episodes of this env) to
  the cell ``floor(obs[:novelty_dims] / novelty_bin)``. Unless novelty is weighted in the overlay,
  the step only queues ``obs[:novelty_dims]``'s bytes and the visits are counted at the episode's
  end (or every 1024 steps, or when :attr:`EconomicMeteringWrapper.episode` is read), which gives
  the same sum.
- the objective overlay (when ``scales`` are given), see ``overlay.py``: the reward is
  ``r_task * keep_task_reward + J(t) - J(t-1)`` with ``J = sum_k scale_k / ref_k * m_k`` over the
  running episode metrics ``m_k``, so each term's episode sum is the episode metric of its key.

Each step is one call of :func:`econmotor.economics.courier_formulas.meter_step` (here with
Python floats, ``xp=PY``), the one definition the ``mjx`` backend's jitted step calls with
``jax.numpy``. The meter and the overlay are one wrapper, with the episode's sums in one tuple:
on the CPU the per-step cost is mostly the code and objects each step touches after MuJoCo
has run (``benchmarks/overlay_overhead.py``).

Episode raw metrics (``info["econ_episode"]`` on the last step) use the keys
:class:`~econmotor.economics.EconomicMeter` reads: ``units_completed``, ``units_attempted``
(``= units_completed + errors``: the leg during which the robot fell counts as attempted and
failed), ``errors``, ``episode_length_s``, ``energy_wh``, ``risk_score`` and ``novelty_score``
(means over steps), plus ``return`` (the env's own reward), ``length_steps``,
``forward_distance_m``, ``control_dt_s`` and ``termination_reason`` (``"fall"`` or
``"max_steps"``), and ``pose_tracking`` (sum of per-step pose similarity) when a
pose-tracking wrapper inside reports ``info["pose_tracking"]``. With the overlay, the last step's
info also holds ``overlay_terms`` (``{key: {"raw": m_k(T), "weighted": factor_k * m_k(T)}}``)
and ``overlay_return`` (``J(T)``).
"""

from __future__ import annotations

import functools
import struct
from collections.abc import Callable, Iterable, Mapping, Sequence
from typing import Any, NamedTuple

import gymnasium as gym
import mujoco
import numpy as np

from econmotor.economics.courier_formulas import (
    PY,
    RUNNING_METRIC_KEYS,
    meter_constants,
    meter_step,
    novelty_bonus,
    novelty_cell_py,
    running_metrics,
)
from econmotor.errors import ConfigError
from econmotor.motor_backend.mujoco.overlay import overlay_term_factors


class VisitNovelty:
    """Visit counts over coarse cells: the n-th visit to cell ``floor(x * inv_bin)`` scores ``1 / sqrt(n)``."""

    __slots__ = ("_cell", "_counts", "dims", "inv_bin")

    def __init__(self, novelty_bin: float, dims: int = 5) -> None:
        self._counts: dict[tuple[int | None, ...], int] = {}  # cell -> visits, kept across episodes
        self.inv_bin = 1.0 / float(novelty_bin)
        self.dims = int(dims)
        self._cell = novelty_cell_py(self.dims)

    @property
    def counts(self) -> dict[tuple[int | None, ...], int]:
        """Visits per cell, keyed by the cell's integer indices (None: a NaN or infinite coordinate)."""
        return dict(self._counts)

    def visit_all(self, points: Iterable[Sequence[float]], total: float) -> float:
        """Count the cells of ``points`` (rows of at least ``dims`` floats); ``total`` plus their scores.

        The points are visited in row order, as they were stepped: visit ``n`` of a cell scores
        ``novelty_bonus(n)``. Rows of Python floats (the wrapper's unpacked queue) are the fast
        case: a cell is one call of the written-out ``novelty_cell_py``, a tuple of ints.
        """
        counts, cell, inv_bin = self._counts, self._cell, self.inv_bin
        get = counts.get
        for point in points:
            key = cell(point, inv_bin)
            n = get(key, 0) + 1
            counts[key] = n
            total += novelty_bonus(n)
        return total


@functools.cache
def _row_reader(dtype: np.dtype, row_items: int, dims: int) -> Callable[[bytes], Iterable[Sequence[float]]]:
    """Reads queued rows (``row_items`` values of ``dtype`` each) back as their first ``dims`` values.

    Native floats: one ``struct`` unpack per row, straight to Python floats (no numpy call per
    episode); any other dtype through numpy.
    """
    dims = min(dims, row_items)
    if dtype.kind == "f" and dtype.isnative and dtype.char in "efd":
        return struct.Struct(f"={dims}{dtype.char}{(row_items - dims) * dtype.itemsize}x").iter_unpack
    return lambda data: np.frombuffer(data, dtype).reshape(-1, row_items)[:, :dims].tolist()


class EpisodeSums(NamedTuple):
    """The running sums of the episode so far (:attr:`EconomicMeteringWrapper.episode`, a snapshot).

    The metric methods give the running episode metrics of the overlay keys (the values the
    episode would report if it ended now).
    """

    steps: int
    units: float
    best_x: float
    errors: float
    energy_wh: float
    risk_sum: float
    novelty_sum: float
    pose_sum: float
    task_return: float
    dt_s: float

    def running_metrics(self) -> tuple[float, float, float, float, float, float]:
        """All six running metrics at once, in :data:`RUNNING_METRIC_KEYS` order."""
        return _running_metrics_of(self[:6], self.novelty_sum, self.pose_sum, self.dt_s)

    def mpl_per_hour(self) -> float:
        """Good units per hour so far: ``units / (steps * dt / 3600)``."""
        return self.running_metrics()[0]

    def error_rate(self) -> float:
        """Errors per attempted unit so far: ``errors / (units + errors)``."""
        return self.running_metrics()[1]

    def energy_kwh(self) -> float:
        return self.running_metrics()[2]

    def risk_score(self) -> float:
        return self.running_metrics()[3]

    def novelty_score(self) -> float:
        return self.running_metrics()[4]

    def pose_tracking(self) -> float:
        return self.pose_sum


def _running_metrics_of(sums: Sequence[Any], novelty_sum: float, pose_sum: float,
                        dt_s: float) -> tuple[float, ...]:
    """:func:`running_metrics` of the meter's sums (in ``courier_formulas.METER_SUMS`` order)."""
    steps, units, _, errors, energy_wh, risk_sum = sums
    return running_metrics(steps, units, errors, energy_wh, risk_sum, novelty_sum, pose_sum, dt_s, PY)


__all__ = ["RUNNING_METRIC_KEYS", "EconomicMeteringWrapper", "EpisodeSums", "VisitNovelty", "actuated_dof_span",
           "find_wrapper"]

#: observations up to this size are queued for novelty whole (hopper: 88 bytes), larger ones as obs[:dims]
_QUEUE_WHOLE_OBS_BYTES = 256

#: queued novelty points (observation bytes) are counted at the latest after this many steps
_MAX_PENDING_VISITS = 1024


def actuated_dof_span(model: Any) -> tuple[int, int]:
    """``(lo, hi)``: the smallest dof range holding every joint-driven actuator's dof.

    Power is summed over ``qfrc_actuator[lo:hi] * qvel[lo:hi]``; unactuated dofs inside the
    range read ``qfrc_actuator = 0`` and add nothing. Any non-joint transmission (tendon,
    site, ...) can push force onto any dof, so then the range is all ``nv`` dofs.
    """
    joint_types = (int(mujoco.mjtTrn.mjTRN_JOINT), int(mujoco.mjtTrn.mjTRN_JOINTINPARENT))
    gravcomp = getattr(model, "jnt_actgravcomp", None)  # actuator gravity compensation also lands there
    if (model.nu == 0 or any(int(t) not in joint_types for t in model.actuator_trntype)
            or (gravcomp is not None and bool(np.any(gravcomp)))):
        return 0, int(model.nv)
    joints = [int(j) for j in model.actuator_trnid[:, 0]]
    ndof = {int(mujoco.mjtJoint.mjJNT_FREE): 6, int(mujoco.mjtJoint.mjJNT_BALL): 3}
    lo = min(int(model.jnt_dofadr[j]) for j in joints)
    hi = max(int(model.jnt_dofadr[j]) + ndof.get(int(model.jnt_type[j]), 1) for j in joints)
    return lo, hi


class EconomicMeteringWrapper(gym.Wrapper):
    """Meter units, energy, falls, risk and novelty of a Gymnasium MuJoCo env; add the overlay (module doc).

    Args:
        env: a Gymnasium MuJoCo env (``env.unwrapped`` has ``model``, ``data`` and ``dt``);
            wrap it *outside* ``TimeLimit`` so truncations are seen.
        leg_distance_m: forward distance of one unit of work, m (> 0).
        drivetrain_efficiency: electrical-to-mechanical efficiency in (0, 1].
        idle_power_w: electrical power drawn while on, W (>= 0).
        tilt_margin_rad: tilt with zero risk, rad.
        fall_tilt_rad: tilt at which risk reaches 1, rad (> tilt_margin_rad).
        novelty_dims: leading observation dims hashed for visit counts (>= 1).
        novelty_bin: bin width of the hash, in observation units (> 0).
        scales: the objective overlay, overlay key -> signed scale (a ``CompiledRewardOverlay`` or
            a plain mapping; keys in ``overlay.TERM_METRICS``). None: no overlay, the reward is
            the env's own and the info has no overlay keys.
        keep_task_reward: with an overlay, keep the env's own reward (True) or use the overlay alone.
        references: overlay key -> positive divisor of its term (missing keys: 1).
    """

    # the wrapper's own state in slots: the step reads a dozen of them, each at a fixed offset of
    # the object (one or two cache lines), not through the instance dict
    __slots__ = ("_constants", "_count_each_step", "_novelty", "_novelty_dims", "_novelty_sum", "_pending",
                 "_pose_sum", "_prev_j", "_qfrc", "_qpos", "_queue_whole_obs", "_qvel", "_read_rows", "_step_extras",
                 "_sums", "_task_return", "_terms", "_track_pose", "_x0", "dt_s", "env", "factors",
                 "keep_task_reward", "leg_distance_m", "overlay", "scales")

    def __init__(self, env: gym.Env, leg_distance_m: float = 10.0, drivetrain_efficiency: float = 0.6,
                 idle_power_w: float = 20.0, tilt_margin_rad: float = 0.2, fall_tilt_rad: float = 1.0,
                 novelty_dims: int = 5, novelty_bin: float = 0.25, scales: Mapping[str, float] | None = None,
                 keep_task_reward: bool = True, references: Mapping[str, float] | None = None) -> None:
        super().__init__(env)
        where = "EconomicMeteringWrapper"
        if not leg_distance_m > 0:
            raise ConfigError(where, "leg_distance_m", f"must be > 0, got {leg_distance_m}")
        if not 0 < drivetrain_efficiency <= 1:
            raise ConfigError(where, "drivetrain_efficiency", f"must be in (0, 1], got {drivetrain_efficiency}")
        if idle_power_w < 0:
            raise ConfigError(where, "idle_power_w", f"must be >= 0, got {idle_power_w}")
        if not fall_tilt_rad > tilt_margin_rad >= 0:
            raise ConfigError(where, "fall_tilt_rad", "need fall_tilt_rad > tilt_margin_rad >= 0")
        if novelty_dims < 1 or not novelty_bin > 0:
            raise ConfigError(where, "novelty_bin", "need novelty_dims >= 1 and novelty_bin > 0")
        base = env.unwrapped
        if not hasattr(base, "data") or not hasattr(base, "model"):
            raise ConfigError(where, "env", f"{base!r} is not a MuJoCo env (no model/data)")
        # memoryviews into MjData's fixed buffers (MjData never reallocates them): they index and
        # iterate as Python floats without numpy's per-call cost
        self._qpos = memoryview(base.data.qpos)
        lo, hi = actuated_dof_span(base.model)
        self._qfrc, self._qvel = memoryview(base.data.qfrc_actuator[lo:hi]), memoryview(base.data.qvel[lo:hi])
        self.dt_s = float(base.dt)
        self.leg_distance_m = float(leg_distance_m)
        # the novelty point is obs[:novelty_dims]: at most the whole observation
        obs_size = int(np.prod(env.observation_space.shape)) if env.observation_space.shape else int(novelty_dims)
        self._novelty_dims = min(int(novelty_dims), obs_size)
        # the overlay: J's coefficients go into the step's constants (all 0 without an overlay)
        self.overlay = scales is not None
        self.scales = {k: float(v) for k, v in (scales or {}).items()}
        self.factors = overlay_term_factors(self.scales, references) if self.overlay else {}
        self.keep_task_reward = bool(keep_task_reward) or not self.overlay
        self._terms = [(k, RUNNING_METRIC_KEYS.index(k)) for k in self.factors]
        free_root = int(base.model.jnt_type[0]) == int(mujoco.mjtJoint.mjJNT_FREE)
        # meter_step's constants as a plain tuple: it unpacks faster than the NamedTuple
        self._constants = tuple(meter_constants(leg_distance_m, drivetrain_efficiency, idle_power_w, self.dt_s,
                                                tilt_margin_rad, fall_tilt_rad, free_root, self.factors, hi - lo))
        self._novelty = VisitNovelty(novelty_bin, self._novelty_dims)
        # per-step reads beyond the physics: novelty weighted (count each step's cell at once) or
        # a pose-tracking wrapper inside (its info["pose_tracking"])
        self._count_each_step = bool(self.factors.get("novelty_score"))
        self._track_pose = _reports_pose_tracking(env)
        self._step_extras = self._count_each_step or self._track_pose
        self._pending: list[bytes] = []  # obs bytes of steps whose novelty cells are not counted yet
        self._queue_whole_obs = False  # queue whole observations or obs[:dims] (set at reset)
        self._read_rows = _row_reader(np.dtype(np.float64), self._novelty_dims, self._novelty_dims)
        self._start_episode(0.0)

    def _start_episode(self, x0: float) -> None:
        self._x0 = x0
        self._sums = (0, 0.0, x0, 0.0, 0.0, 0.0)  # courier_formulas.METER_SUMS
        self._novelty_sum = self._pose_sum = self._task_return = self._prev_j = 0.0

    @property
    def episode(self) -> EpisodeSums:
        """The current episode's running sums (counts the queued novelty visits first)."""
        self.flush_visits()
        return EpisodeSums(*self._sums, self._novelty_sum, self._pose_sum, self._task_return, self.dt_s)

    @property
    def x0(self) -> float:
        """The root's x at the episode's start, m."""
        return self._x0

    @property
    def visit_counts(self) -> dict[tuple[int, ...], int]:
        """Visits per novelty cell ``floor(obs[:novelty_dims] / novelty_bin)``, across episodes."""
        self.flush_visits()
        return self._novelty.counts

    def flush_visits(self) -> None:
        """Count the queued novelty points into the visit counts and the episode's novelty sum."""
        pending = self._pending
        if pending:
            self._novelty_sum = self._novelty.visit_all(self._read_rows(b"".join(pending)), self._novelty_sum)
            pending.clear()

    def reset(self, **kwargs: Any):
        obs, info = self.env.reset(**kwargs)
        self.flush_visits()  # an episode cut short: its visits still count for the cells
        # a small observation is queued whole (one copy, no slice); a large one only obs[:dims]
        self._queue_whole_obs = obs.nbytes <= _QUEUE_WHOLE_OBS_BYTES
        row_items = obs.size if self._queue_whole_obs else min(obs.size, self._novelty_dims)
        self._read_rows = _row_reader(obs.dtype, row_items, self._novelty_dims)
        self._start_episode(self._qpos[0])
        return obs, info

    def step(self, action):
        obs, reward, terminated, truncated, info = self.env.step(action)
        reward = float(reward)
        pending = self._pending  # this step's novelty cell is counted later (module doc)
        pending.append(obs.tobytes() if self._queue_whole_obs else obs[: self._novelty_dims].tobytes())
        if self._step_extras:
            self._read_step_extras(info)
        self._sums, j = meter_step(self._sums, self._qpos, self._qfrc, self._qvel, terminated, self._novelty_sum,
                                   self._pose_sum, self._constants, PY)
        self._task_return += reward
        overlay_r = j - self._prev_j  # J(t) - J(t-1); J = 0 without an overlay
        self._prev_j = j
        if terminated or truncated:
            self._end_episode(info, terminated, j)
        elif len(pending) >= _MAX_PENDING_VISITS:
            self.flush_visits()
        return obs, (reward + overlay_r if self.keep_task_reward else overlay_r), terminated, truncated, info

    def _read_step_extras(self, info: dict[str, Any]) -> None:
        if self._count_each_step:  # the overlay weights novelty: J reads this step's bonus
            self.flush_visits()
        if self._track_pose:
            pose = info.get("pose_tracking")
            if pose is not None:
                self._pose_sum += pose

    def _end_episode(self, info: dict[str, Any], fell: bool, j: float) -> None:
        """Add the episode's raw metrics (and the overlay's terms) to the last step's ``info``."""
        # from the wrapper's fields, not an EpisodeSums snapshot: this code runs once per episode, with
        # cold caches, so each instruction it skips counts (~0.4 us per Hopper step in an A/B)
        self.flush_visits()
        steps, units, best_x, errors, energy_wh, _ = sums = self._sums
        dt_s = self.dt_s
        metrics = _running_metrics_of(sums, self._novelty_sum, self._pose_sum, dt_s)
        raw: dict[str, Any] = {
            "units_completed": units,
            "units_attempted": units + errors,
            "errors": errors,
            "episode_length_s": steps * dt_s,
            "length_steps": float(steps),
            "control_dt_s": dt_s,
            "energy_wh": energy_wh,
            "risk_score": metrics[3],
            "novelty_score": metrics[4],
            "return": self._task_return,
            "forward_distance_m": best_x - self._x0,
            "termination_reason": "fall" if fell else "max_steps",
        }
        if self._track_pose:
            raw["pose_tracking"] = self._pose_sum
        info["econ_episode"] = raw
        if self.overlay:  # each term's episode sum telescopes to the episode's metric m_k(T)
            factors = self.factors
            info["overlay_terms"] = {k: {"raw": metrics[i], "weighted": factors[k] * metrics[i]}
                                     for k, i in self._terms}
            info["overlay_return"] = j  # J(T) = sum_k factor_k * m_k(T), the weighted terms' sum


def _reports_pose_tracking(env: gym.Env) -> bool:
    """Whether a wrapper in ``env``'s chain writes ``info["pose_tracking"]`` (its class: ``reports_pose_tracking``)."""
    while env is not None:
        if getattr(type(env), "reports_pose_tracking", False):
            return True
        env = getattr(env, "env", None)
    return False


def find_wrapper(env: gym.Env, cls: type) -> Any:
    """The first wrapper of type ``cls`` in ``env``'s wrapper chain, or None."""
    while env is not None:
        if isinstance(env, cls):
            return env
        env = getattr(env, "env", None)
    return None
