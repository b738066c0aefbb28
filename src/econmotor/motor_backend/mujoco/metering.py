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
  the cell ``floor(obs[:novelty_dims] / novelty_bin)``.
- the objective overlay (when ``scales`` are given), see ``couriers/overlay.py``: the reward is
  ``r_task * keep_task_reward + J(t) - J(t-1)`` with ``J = sum_k scale_k / ref_k * m_k`` over the
  running episode metrics ``m_k``, so each term's episode sum is the episode metric of its key.

Each step reads the physics into a :class:`~econmotor.economics.courier_formulas.StepReading`
and calls :func:`~econmotor.economics.courier_formulas.meter_step` (which adds the step to the
episode's :class:`~econmotor.economics.courier_formulas.MeterSums` in place), ``running_metrics``
and ``overlay_potential`` with Python floats (``xp=PY``): the same functions the ``mjx``
backend's jitted step calls with ``jax.numpy``. The meter and the overlay are one wrapper.

Episode raw metrics (``info["econ_episode"]`` on the last step) use the keys
:class:`~econmotor.economics.EconomicMeter` reads: ``units_completed``, ``units_attempted``
(``= units_completed + errors``: the leg during which the robot fell counts as attempted and
failed), ``errors``, ``episode_length_s``, ``energy_wh``, ``risk_score`` and ``novelty_score``
(means over steps; novelty only where it is metered: always, except in training envs whose
overlay does not reward it), plus ``return`` (the env's own reward), ``length_steps``,
``forward_distance_m``, ``control_dt_s`` and ``termination_reason`` (``"fall"`` or
``"max_steps"``), and ``pose_tracking`` (sum of per-step pose similarity) when a
pose-tracking wrapper inside reports ``info["pose_tracking"]``. With the overlay, the last step's
info also holds ``overlay_terms`` (``{key: {"raw": m_k(T), "weighted": factor_k * m_k(T)}}``)
and ``overlay_return`` (``J(T)``).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from typing import Any, NamedTuple

import gymnasium as gym
import numpy as np

from econmotor.couriers.overlay import overlay_term_factors
from econmotor.couriers.physics import actuated_dof_span, has_free_root, root_tilt_rad
from econmotor.economics.courier_formulas import (
    PY,
    MeterConstants,
    MeterSums,
    RunningMetrics,
    StepReading,
    mechanical_power_w,
    meter_step,
    novelty_bonus,
    novelty_cell,
    overlay_coefficients,
    overlay_potential,
    running_metrics,
)
from econmotor.economics.termination import TerminationReason
from econmotor.errors import ConfigError

__all__ = ["EconomicMeteringWrapper", "EpisodeSums", "VisitNovelty", "actuated_dof_span", "find_wrapper"]


class VisitNovelty:
    """Visit counts over coarse cells: the n-th visit to cell ``floor(x / novelty_bin)`` scores ``1 / sqrt(n)``.

    A cell is keyed by the bytes of its floored coordinates as float64 (one compact object per key,
    so a lookup compares one buffer); :attr:`cells` reads the keys back as tuples of indices, with
    None for a non-finite one (``floor`` keeps NaN and infinities, so such a coordinate still counts).
    """

    def __init__(self, novelty_bin: float, dims: int = 5) -> None:
        self.counts: dict[bytes, int] = {}  # cell's bytes -> visits, kept across episodes
        self.novelty_bin = float(novelty_bin)
        self.dims = int(dims)

    def visit(self, point: np.ndarray) -> float:
        """Count a visit to the cell of ``point[:dims]`` (a 1-d array); its bonus ``novelty_bonus(n)``."""
        cell = novelty_cell(point[: self.dims], self.novelty_bin, np).astype(np.float64, copy=False).tobytes()
        n = self.counts.get(cell, 0) + 1
        self.counts[cell] = n
        return novelty_bonus(n)

    @property
    def cells(self) -> dict[tuple[float | None, ...], int]:
        """Visits per cell, keyed by the cell's indices (None: a non-finite index; such cells add up)."""
        out: dict[tuple[float | None, ...], int] = {}
        for key, n in self.counts.items():
            cell = tuple(v if math.isfinite(v) else None for v in np.frombuffer(key).tolist())
            out[cell] = out.get(cell, 0) + n
        return out


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

    def running_metrics(self) -> RunningMetrics:
        """All six running metrics at once (:class:`~econmotor.economics.courier_formulas.RunningMetrics`)."""
        return running_metrics(MeterSums(*self[: len(dataclasses.fields(MeterSums))]), self.dt_s, PY)

    def mpl_per_hour(self) -> float:
        """Good units per hour so far: ``units / (steps * dt / 3600)``."""
        return self.running_metrics().mpl_per_hour

    def error_rate(self) -> float:
        """Errors per attempted unit so far: ``errors / (units + errors)``."""
        return self.running_metrics().error_rate

    def energy_kwh(self) -> float:
        return self.running_metrics().energy_kwh

    def risk_score(self) -> float:
        return self.running_metrics().risk_score

    def novelty_score(self) -> float:
        return self.running_metrics().novelty_score

    def pose_tracking(self) -> float:
        return self.pose_sum


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
        novelty_dims: leading observation dims hashed for visit counts (>= 1; at most the whole observation).
        novelty_bin: bin width of the hash, in observation units (> 0).
        scales: the objective overlay, overlay key -> signed scale (a ``CompiledRewardOverlay`` or
            a plain mapping; keys in ``couriers.overlay.TERM_METRICS``). None: no overlay, the
            reward is the env's own and the info has no overlay keys.
        keep_task_reward: with an overlay, keep the env's own reward (True) or use the overlay alone.
        references: overlay key -> positive divisor of its term (missing keys: 1).
        meter_novelty: count visits and report ``novelty_score`` (True), or only when the overlay
            rewards novelty (False: what training builds, as nothing else reads a training
            episode's novelty; it is the wrapper's costliest term, a dict of visited cells).
    """

    def __init__(self, env: gym.Env, leg_distance_m: float = 10.0, drivetrain_efficiency: float = 0.6,
                 idle_power_w: float = 20.0, tilt_margin_rad: float = 0.2, fall_tilt_rad: float = 1.0,
                 novelty_dims: int = 5, novelty_bin: float = 0.25, scales: Mapping[str, float] | None = None,
                 keep_task_reward: bool = True, references: Mapping[str, float] | None = None,
                 meter_novelty: bool = True) -> None:
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
        lo, hi = actuated_dof_span(base.model)
        # views into MjData's buffers (fixed for the env's life): the positions, the actuated dofs'
        # forces and velocities
        self._qpos = base.data.qpos
        self._qfrc, self._qvel = base.data.qfrc_actuator[lo:hi], base.data.qvel[lo:hi]
        self._free_root = has_free_root(base.model)
        self.dt_s = float(base.dt)
        self.leg_distance_m = float(leg_distance_m)
        self.constants = MeterConstants(float(leg_distance_m), float(drivetrain_efficiency), float(idle_power_w),
                                        self.dt_s, float(tilt_margin_rad), float(fall_tilt_rad))
        self.overlay = scales is not None
        self.scales = {k: float(v) for k, v in (scales or {}).items()}
        obs_size = int(np.prod(env.observation_space.shape)) if env.observation_space.shape else int(novelty_dims)
        self._novelty = (VisitNovelty(novelty_bin, min(int(novelty_dims), obs_size))
                         if meter_novelty or "novelty_score" in self.scales else None)
        self.factors = overlay_term_factors(self.scales, references) if self.overlay else {}
        self.keep_task_reward = bool(keep_task_reward) or not self.overlay
        self._coefficients = overlay_coefficients(self.factors, self.dt_s)
        self._track_pose = _reports_pose_tracking(env)
        self._start_episode(0.0)

    def _start_episode(self, x0: float) -> None:
        self._x0 = x0
        self._sums = MeterSums(best_x=x0)
        self._task_return = self._prev_j = 0.0

    @property
    def episode(self) -> EpisodeSums:
        """The current episode's running sums."""
        return EpisodeSums(**dataclasses.asdict(self._sums), task_return=self._task_return, dt_s=self.dt_s)

    @property
    def x0(self) -> float:
        """The root's x at the episode's start, m."""
        return self._x0

    @property
    def visit_counts(self) -> dict[tuple[float | None, ...], int]:
        """Visits per novelty cell ``floor(obs[:novelty_dims] / novelty_bin)``, across episodes (a copy)."""
        return self._novelty.cells if self._novelty is not None else {}

    def reset(self, **kwargs: Any):
        obs, info = self.env.reset(**kwargs)
        self._start_episode(float(self._qpos[0]))
        return obs, info

    def step(self, action):
        obs, reward, terminated, truncated, info = self.env.step(action)
        qpos = self._qpos.tolist()
        reading = StepReading(
            x_m=qpos[0],
            mechanical_w=mechanical_power_w(self._qfrc.tolist(), self._qvel.tolist(), PY),
            tilt_rad=root_tilt_rad(qpos, self._free_root, PY),
            fell=terminated,
            novelty_bonus=self._novelty.visit(obs) if self._novelty is not None else 0.0,
            pose_similarity=(info.get("pose_tracking") or 0.0) if self._track_pose else 0.0,
        )
        meter_step(self._sums, reading, self.constants, PY)
        reward = float(reward)
        self._task_return += reward
        j = overlay_potential(self._sums, self._coefficients, PY) if self.overlay else 0.0
        overlay_r = j - self._prev_j  # J(t) - J(t-1); J = 0 without an overlay
        self._prev_j = j
        if terminated or truncated:
            self._end_episode(info, terminated, j)
        return obs, (reward + overlay_r if self.keep_task_reward else overlay_r), terminated, truncated, info

    def _end_episode(self, info: dict[str, Any], fell: bool, j: float) -> None:
        """Add the episode's raw metrics (and the overlay's terms) to the last step's ``info``."""
        sums, dt_s = self._sums, self.dt_s
        metrics = running_metrics(sums, dt_s, PY)
        raw: dict[str, Any] = {
            "units_completed": sums.units,
            "units_attempted": sums.units + sums.errors,
            "errors": sums.errors,
            "episode_length_s": sums.steps * dt_s,
            "length_steps": float(sums.steps),
            "control_dt_s": dt_s,
            "energy_wh": sums.energy_wh,
            "risk_score": metrics.risk_score,
            "return": self._task_return,
            "forward_distance_m": sums.best_x - self._x0,
            "termination_reason": TerminationReason.FALL if fell else TerminationReason.MAX_STEPS,
        }
        if self._novelty is not None:
            raw["novelty_score"] = metrics.novelty_score
        if self._track_pose:
            raw["pose_tracking"] = sums.pose_sum
        info["econ_episode"] = raw
        if self.overlay:  # each term's episode sum telescopes to the episode's metric m_k(T)
            info["overlay_terms"] = {k: {"raw": getattr(metrics, k), "weighted": f * getattr(metrics, k)}
                                     for k, f in self.factors.items()}
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
