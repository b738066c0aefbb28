"""EconomicMeteringWrapper: read the economics of a MuJoCo rollout from the physics.

Per control step (duration ``dt = frame_skip * timestep`` s), from ``env.unwrapped.data``:

- units: a *delivery leg* is ``leg_distance_m`` of forward (+x) travel of the root.
  Progress is a high-water mark, so moving back and forth earns nothing:
  ``units_t = (max_{s<=t} x_s - x_0) / leg_distance_m`` (fractional legs).
- electrical energy, Wh: mechanical power ``P_mech = sum_j |qfrc_actuator_j * qvel_j|`` W over
  the degrees of freedom (``qfrc_actuator`` is the actuator force *after* the gear; unactuated
  dofs read 0, so the sum runs over :func:`actuated_dof_span` only), electrical
  ``P_el = P_mech / drivetrain_efficiency + idle_power_w``,
  ``energy_wh += P_el * dt / 3600``. Power is sampled at the end of each control step.
- falls: the env's own unhealthy termination (``terminated=True``) is one fall = one error.
- risk in [0, 1]: ``clip((tilt - tilt_margin_rad) / (fall_tilt_rad - tilt_margin_rad), 0, 1)``,
  tilt = the torso's angle from upright (planar robots: the root hinge; free-floating robots:
  from the root quaternion, ``cos(tilt) = 1 - 2 (qx^2 + qy^2)``).
- novelty: ``1 / sqrt(n(s))`` where ``n`` counts visits (kept across episodes of this env) to
  the cell ``floor(obs[:novelty_dims] / novelty_bin)``. The step only queues ``obs[:novelty_dims]``'s
  bytes; the visits are counted when ``tally.novelty_sum`` is read (by the overlay when it
  weights novelty, at the episode's end, or every 1024 steps), which gives the same sum.

Every formula is :mod:`econmotor.economics.courier_formulas`' (called here with Python floats,
``xp=PY``), the one definition the ``mjx`` backend's jitted step calls with ``jax.numpy``.

Episode raw metrics (``info["econ_episode"]`` on the last step) use the keys
:class:`~econmotor.economics.EconomicMeter` reads: ``units_completed``, ``units_attempted``
(``= units_completed + errors``: the leg during which the robot fell counts as attempted and
failed), ``errors``, ``episode_length_s``, ``energy_wh``, ``risk_score`` and ``novelty_score``
(means over steps), plus ``return`` (the env's own reward), ``length_steps``,
``forward_distance_m``, ``control_dt_s`` and ``termination_reason`` (``"fall"`` or
``"max_steps"``), and ``pose_tracking`` (sum of per-step pose similarity) when a
pose-tracking wrapper reports ``info["pose_tracking"]``.
"""

from __future__ import annotations

import math
from typing import Any

import gymnasium as gym
import mujoco
import numpy as np

from econmotor.economics.courier_formulas import (
    PY,
    RUNNING_METRIC_KEYS,
    free_tilt_rad,
    high_water_units,
    novelty_bonus,
    novelty_cell,
    planar_tilt_rad,
    running_metrics,
    step_energy_wh,
    tilt_risk,
)
from econmotor.errors import ConfigError


class VisitNovelty:
    """Visit counts over coarse cells: the n-th visit to cell ``floor(x * inv_bin)`` scores ``1 / sqrt(n)``."""

    __slots__ = ("_counts", "dims", "inv_bin")

    def __init__(self, novelty_bin: float, dims: int = 5) -> None:
        self._counts: dict[bytes, int] = {}  # cell (its int64 indices' bytes) -> visits, kept across episodes
        self.inv_bin = 1.0 / float(novelty_bin)
        self.dims = int(dims)

    @property
    def counts(self) -> dict[tuple[int, ...], int]:
        """Visits per cell, keyed by the cell's integer indices."""
        return {tuple(np.frombuffer(key, np.int64).tolist()): n for key, n in self._counts.items()}

    def visit_all(self, points: np.ndarray, total: float) -> float:
        """Count the cells of ``points`` (rows: observations' first ``dims`` entries); ``total`` plus their scores.

        The points are visited in row order, as they were stepped: visit ``n`` of a cell scores
        ``novelty_bonus(n)``. numpy computes the cells in one pass and hands each row over as the
        bytes of its int64 indices (an exact dict key, cheap to hash); the loop is plain dict work.
        """
        cells = novelty_cell(points[:, : self.dims], self.inv_bin, np).astype(np.int64)  # C-contiguous rows
        row_bytes = np.dtype((np.void, cells.itemsize * cells.shape[1]))  # one key per row
        counts = self._counts
        get = counts.get
        for key in cells.view(row_bytes).ravel().tolist():
            n = get(key, 0) + 1
            counts[key] = n
            total += novelty_bonus(n)
        return total


class EpisodeTally:
    """Running sums of one episode; the overlay reads the running episode metrics from here.

    The meter queues each step's novelty point in ``pending_visits`` (the raw bytes of the
    observation or of its first ``dims`` entries, of dtype ``visit_dtype``); reading
    ``novelty_sum`` counts the queued points first (the same sum as counting at each step),
    which keeps the hashing off the step path when nobody reads novelty every step.
    """

    __slots__ = (
        "_novelty",
        "_novelty_sum",
        "dt_s",
        "energy_wh",
        "errors",
        "pending_visits",
        "pose_sum",
        "risk_sum",
        "steps",
        "task_return",
        "units",
        "visit_dtype",
    )

    def __init__(self, dt_s: float, novelty: VisitNovelty | None = None) -> None:
        self.dt_s = dt_s
        self._novelty = novelty
        self.pending_visits: list[bytes] = []  # obs[:dims].tobytes() of steps whose cells are not counted yet
        self.visit_dtype = np.dtype(np.float64)  # the dtype of those bytes (the meter sets the env's at reset)
        self.reset()

    def reset(self) -> None:
        if self.pending_visits:
            self.flush_visits()  # the cells' counts outlive the episode
        self.steps = 0
        self.units = self.errors = self.energy_wh = 0.0
        self.risk_sum = self._novelty_sum = self.pose_sum = self.task_return = 0.0

    def flush_visits(self) -> None:
        """Count the queued novelty points into the visit counts and ``novelty_sum``."""
        if self._novelty is None:
            raise ValueError("EpisodeTally has queued visits but no VisitNovelty to count them")
        pending = self.pending_visits
        if not pending:
            return
        points = np.frombuffer(b"".join(pending), self.visit_dtype).reshape(len(pending), -1)
        self._novelty_sum = self._novelty.visit_all(points, self._novelty_sum)
        pending.clear()

    @property
    def novelty_sum(self) -> float:
        """Sum over this episode's steps of the novelty bonus ``1 / sqrt(n)``."""
        if self.pending_visits:
            self.flush_visits()
        return self._novelty_sum

    # running episode metrics (the values the episode would report if it ended now)
    def _metrics(self, novelty_sum: float = 0.0) -> tuple[float, float, float, float, float, float]:
        return running_metrics(self.steps, self.units, self.errors, self.energy_wh, self.risk_sum, novelty_sum,
                               self.pose_sum, self.dt_s, PY)

    def mpl_per_hour(self) -> float:
        """Good units per hour so far: ``units / (steps * dt / 3600)``."""
        return self._metrics()[0]

    def error_rate(self) -> float:
        """Errors per attempted unit so far: ``errors / (units + errors)``."""
        return self._metrics()[1]

    def energy_kwh(self) -> float:
        return self._metrics()[2]

    def risk_score(self) -> float:
        return self._metrics()[3]

    def novelty_score(self) -> float:
        return self._metrics(self.novelty_sum)[4]  # reading novelty_sum counts the queued visits

    def pose_tracking(self) -> float:
        return self.pose_sum

    def running_metrics(self) -> tuple[float, float, float, float, float, float]:
        """All six running metrics at once, in :data:`RUNNING_METRIC_KEYS` order."""
        return self._metrics(self.novelty_sum)


__all__ = ["RUNNING_METRIC_KEYS", "EconomicMeteringWrapper", "EpisodeTally", "VisitNovelty", "actuated_dof_span",
           "find_wrapper"]

#: at most this many actuated dofs (hopper: 3, humanoid: 17): power summed over Python floats; more: numpy.
_SMALL_DOFS = 32

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
    """Meter units, energy, falls, risk and novelty of a Gymnasium MuJoCo env (see module doc).

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
    """

    def __init__(self, env: gym.Env, leg_distance_m: float = 10.0, drivetrain_efficiency: float = 0.6,
                 idle_power_w: float = 20.0, tilt_margin_rad: float = 0.2, fall_tilt_rad: float = 1.0,
                 novelty_dims: int = 5, novelty_bin: float = 0.25) -> None:
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
        self._data = base.data
        # views into MjData's fixed buffers, read every step (MjData never reallocates them);
        # memoryviews index to Python floats without numpy's per-call cost
        self._qpos = memoryview(base.data.qpos)
        lo, hi = actuated_dof_span(base.model)
        self._qfrc, self._qvel = base.data.qfrc_actuator[lo:hi], base.data.qvel[lo:hi]
        if hi - lo <= _SMALL_DOFS:  # a few dofs: Python floats beat numpy's per-call cost
            self._energy_args = (memoryview(self._qfrc), memoryview(self._qvel))
            self._energy_xp = PY
        else:
            self._energy_args, self._energy_xp = (self._qfrc, self._qvel), np
        self.dt_s = float(base.dt)
        self.leg_distance_m = float(leg_distance_m)
        self._inv_eff = 1.0 / float(drivetrain_efficiency)
        self._idle_w = float(idle_power_w)
        self._tilt_margin = float(tilt_margin_rad)
        self._tilt_span = float(fall_tilt_rad - tilt_margin_rad)
        self._novelty_dims = int(novelty_dims)
        self._free_root = int(base.model.jnt_type[0]) == int(mujoco.mjtJoint.mjJNT_FREE)
        # risk is 0 while tilt <= margin, so tilt_risk runs only past it. Free root: tilt > margin
        # <=> cos(tilt) < cos(margin), so acos runs only near or past the margin (the 1e-9 slack
        # keeps every step acos would have scored > 0)
        self._cos_margin = math.cos(self._tilt_margin) + 1e-9
        self._novelty = VisitNovelty(novelty_bin, novelty_dims)
        self.tally = EpisodeTally(self.dt_s, self._novelty)
        self._pending_visits = self.tally.pending_visits  # the same list object for the env's life
        self._x0 = self._best_x = 0.0
        self._queue_whole_obs = False

    @property
    def visit_counts(self) -> dict[tuple[int, ...], int]:
        """Visits per novelty cell ``floor(obs[:novelty_dims] / novelty_bin)``, across episodes."""
        self.tally.flush_visits()
        return self._novelty.counts

    def tilt_rad(self) -> float:
        """The torso's angle from upright, rad."""
        qpos = self._data.qpos
        if self._free_root:
            return free_tilt_rad(float(qpos[4]), float(qpos[5]), PY)
        return planar_tilt_rad(float(qpos[2]), PY)

    def reset(self, **kwargs: Any):
        obs, info = self.env.reset(**kwargs)
        self.tally.reset()  # counts the last episode's queued visits
        self.tally.visit_dtype = obs.dtype
        # a small observation is queued whole (one copy, no slice); a large one only obs[:dims]
        self._queue_whole_obs = obs.nbytes <= _QUEUE_WHOLE_OBS_BYTES
        self._x0 = self._best_x = self._qpos[0]
        return obs, info

    def step(self, action):
        obs, reward, terminated, truncated, info = self.env.step(action)
        tally, qpos = self.tally, self._qpos
        tally.steps += 1
        tally.task_return += float(reward)
        x = qpos[0]
        if x > self._best_x:  # else no progress: the high-water mark stays
            gain, self._best_x = high_water_units(x, self._best_x, self.leg_distance_m, PY)
            tally.units += gain
        f, v = self._energy_args  # a call with *args would leave CPython's inlined calls
        tally.energy_wh += step_energy_wh(f, v, self._inv_eff, self._idle_w, self.dt_s, self._energy_xp)
        if self._free_root:
            qx, qy = qpos[4], qpos[5]
            if 1.0 - 2.0 * (qx * qx + qy * qy) < self._cos_margin:
                tally.risk_sum += tilt_risk(free_tilt_rad(qx, qy, PY), self._tilt_margin, self._tilt_span, PY)
        else:
            angle = qpos[2]
            if angle > self._tilt_margin or -angle > self._tilt_margin:  # else the risk is 0
                tally.risk_sum += tilt_risk(planar_tilt_rad(angle, PY), self._tilt_margin, self._tilt_span, PY)
        pending = self._pending_visits  # this step's cell is counted when novelty_sum is read:
        pending.append(obs.tobytes() if self._queue_whole_obs else obs[: self._novelty_dims].tobytes())
        pose = info.get("pose_tracking") if info else None
        if pose is not None:
            tally.pose_sum += pose
        if terminated or truncated:
            if terminated:  # the env's own unhealthy termination: one fall
                tally.errors += 1.0
            info["econ_episode"] = self.episode_raw_metrics(terminated, pose is not None)
        elif len(pending) >= _MAX_PENDING_VISITS:
            tally.flush_visits()
        return obs, reward, terminated, truncated, info

    def episode_raw_metrics(self, fell: bool, with_pose: bool = False) -> dict[str, Any]:
        """The episode's raw metrics so far (keys in the module docstring)."""
        t = self.tally
        _, _, _, risk_score, novelty_score, _ = t.running_metrics()
        out: dict[str, Any] = {
            "units_completed": t.units,
            "units_attempted": t.units + t.errors,
            "errors": t.errors,
            "episode_length_s": t.steps * self.dt_s,
            "length_steps": float(t.steps),
            "control_dt_s": self.dt_s,
            "energy_wh": t.energy_wh,
            "risk_score": risk_score,
            "novelty_score": novelty_score,
            "return": t.task_return,
            "forward_distance_m": self._best_x - self._x0,
            "termination_reason": "fall" if fell else "max_steps",
        }
        if with_pose:
            out["pose_tracking"] = t.pose_sum
        return out


def find_wrapper(env: gym.Env, cls: type) -> Any:
    """The first wrapper of type ``cls`` in ``env``'s wrapper chain, or None."""
    while env is not None:
        if isinstance(env, cls):
            return env
        env = getattr(env, "env", None)
    return None
