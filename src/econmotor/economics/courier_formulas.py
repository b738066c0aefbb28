"""The courier economics, written once against an array namespace.

Every formula takes ``xp``, the namespace its arguments live in, and uses only what all
three namespaces provide:

- :data:`PY` — Python floats (the ``mujoco`` backend's per-step path: no array overhead),
- ``numpy`` — arrays on the host,
- ``jax.numpy`` — traced arrays inside the ``mjx`` backend's jitted, vmapped step.

The NumPy/MuJoCo path (``motor_backend/mujoco/metering.py``, ``overlay.py``) and the JAX path
(``motor_backend/mjx/env.py``) both call these functions; neither keeps its own copy.

Per control step of ``dt_s`` seconds (see ``mujoco/metering.py`` for the story):

- units: ``best_x' = max(best_x, x)``; ``units += (best_x' - best_x) / leg_distance_m``
  (a high-water mark: moving back and forth earns nothing),
- energy (:func:`step_energy_wh`): mechanical power ``sum_j |qfrc_actuator_j * qvel_j|`` W over the
  actuated dofs; electrical ``P_el = P_mech / drivetrain_efficiency + idle_power_w``;
  ``energy_wh += P_el * dt_s / 3600``,
- tilt: planar robots ``|root hinge angle|``; free-floating ``acos(1 - 2 (qx^2 + qy^2))``;
  risk ``clip((tilt - tilt_margin_rad) / (fall_tilt_rad - tilt_margin_rad), 0, 1)``,
- falls: Gymnasium's v5 healthy checks (:func:`healthy_rule`, :func:`is_healthy`): not healthy = one fall = one error,
- novelty: visit ``n`` of cell ``floor(obs[:novelty_dims] / novelty_bin)`` scores ``n ** -0.5``,
- running episode metrics (:func:`running_metrics`) and the overlay potential
  ``J = sum_k factor_k * m_k`` (:func:`overlay_potential`); a step's overlay reward is
  ``J(t) - J(t-1)``, so each term's episode sum is the episode metric of its key.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

#: overlay keys in the order :func:`running_metrics` returns them.
RUNNING_METRIC_KEYS = ("mpl_per_hour", "error_rate", "energy_kwh", "risk_score", "novelty_score", "pose_tracking")

SECONDS_PER_HOUR = 3600.0
WH_PER_KWH = 1000.0


class _PythonFloats:
    """The array namespace of plain Python floats (the CPU per-step path)."""

    maximum = staticmethod(max)
    minimum = staticmethod(min)
    abs = staticmethod(abs)
    sqrt = staticmethod(math.sqrt)
    floor = staticmethod(math.floor)
    isfinite = staticmethod(math.isfinite)

    arccos = staticmethod(math.acos)

    @staticmethod
    def clip(x: float, lo: float, hi: float) -> float:
        return lo if x < lo else hi if x > hi else x

    @staticmethod
    def where(cond: Any, a: Any, b: Any) -> Any:
        return a if cond else b

    @staticmethod
    def logical_and(a: Any, b: Any) -> bool:
        return bool(a and b)

    @staticmethod
    def all(values: Any) -> bool:
        return all(values)

    @staticmethod
    def sum(values: Any) -> float:
        return sum(values)


#: plain Python floats as an array namespace (``math`` plus ``max``/``min``/``abs``).
PY = _PythonFloats()


def safe_div(num: Any, den: Any, xp: Any) -> Any:
    """``num / den`` where ``den > 0``, else 0 (no division by zero is evaluated)."""
    if xp is PY:
        return num / den if den > 0 else 0.0
    positive = den > 0
    return xp.where(positive, num / xp.where(positive, den, 1.0), 0.0)


# ---------------------------------------------------------------- per-step metering
def high_water_units(x: Any, best_x: Any, leg_distance_m: float, xp: Any) -> tuple[Any, Any]:
    """``(legs gained this step, new best x)``: forward progress past the best x so far, in legs."""
    best = (x if x > best_x else best_x) if xp is PY else xp.maximum(best_x, x)
    return (best - best_x) / leg_distance_m, best


def step_energy_wh(qfrc_actuator: Any, qvel: Any, inv_efficiency: float, idle_power_w: float, dt_s: float,
                   xp: Any) -> Any:
    """Electrical Wh of one control step over the actuated dofs (the last axis).

    Mechanical power ``P_mech = sum_j |qfrc_actuator_j * qvel_j|`` W; electrical
    ``P_el = P_mech * inv_efficiency + idle_power_w`` (``inv_efficiency = 1 / drivetrain_efficiency``);
    energy ``P_el * dt_s / 3600`` Wh.
    """
    if xp is PY:  # memoryviews or sequences of floats: a plain loop (no numpy per-call cost, warm bytecode)
        mech_w = 0.0
        for f, v in zip(qfrc_actuator, qvel, strict=True):
            mech_w += abs(f * v)
    else:
        mech_w = xp.sum(xp.abs(qfrc_actuator * qvel), axis=-1)
    return (mech_w * inv_efficiency + idle_power_w) * (dt_s / SECONDS_PER_HOUR)


def planar_tilt_rad(root_angle: Any, xp: Any) -> Any:
    """Tilt of a planar robot: the absolute root hinge angle."""
    return xp.abs(root_angle)


def free_tilt_rad(qx: Any, qy: Any, xp: Any) -> Any:
    """Tilt from upright of a free root with quaternion ``(w, qx, qy, qz)``: ``acos(1 - 2 (qx^2 + qy^2))``."""
    c = 1.0 - 2.0 * (qx * qx + qy * qy)
    if xp is PY:  # the clip inline (c <= 1 always)
        return math.acos(c if c > -1.0 else -1.0)
    return xp.arccos(xp.clip(c, -1.0, 1.0))


def tilt_risk(tilt_rad: Any, tilt_margin_rad: float, tilt_span_rad: float, xp: Any) -> Any:
    """Risk in [0, 1]: ``clip((tilt - margin) / span, 0, 1)``, ``span = fall_tilt - margin``."""
    risk = (tilt_rad - tilt_margin_rad) / tilt_span_rad
    if xp is PY:  # the clip inline
        return 0.0 if risk < 0.0 else 1.0 if risk > 1.0 else risk
    return xp.clip(risk, 0.0, 1.0)


def novelty_bonus(visits: Any) -> Any:
    """The bonus of the ``visits``-th visit to a cell: ``visits ** -0.5``."""
    return visits ** -0.5


def novelty_cell(point: Any, inv_bin: float, xp: Any) -> Any:
    """The cell index of a point: ``floor(point / novelty_bin)`` per dim (``inv_bin = 1 / bin``)."""
    if xp is PY:
        return tuple([math.floor(v * inv_bin) for v in point])
    return xp.floor(point * inv_bin)


# ---------------------------------------------------------------- falls (Gymnasium v5 healthy checks)
@dataclass(frozen=True)
class HealthyRule:
    """Gymnasium v5's ``is_healthy`` of one robot (the ranges come from the env's own parameters)."""

    z_index: int
    z_range: tuple[float, float]
    inclusive: bool = False  # Ant-v5: lo <= z <= hi; the others: lo < z < hi
    angle_range: tuple[float, float] | None = None  # planar robots: qpos[2]
    state_range: tuple[float, float] | None = None  # Hopper-v5: every entry of state_vector()[2:]
    finite: bool = False  # Ant-v5: the whole state vector is finite


def healthy_rule(robot: str, params: Mapping[str, Any]) -> HealthyRule:
    """The :class:`HealthyRule` of ``robot`` given its Gymnasium constructor ``params``.

    Hopper-v5: ``all(lo < state_vector()[2:] < hi)``, ``z = qpos[1]``, ``angle = qpos[2]`` in open
    ranges; Walker2d-v5: z and angle; Ant-v5: finite state, ``lo <= qpos[2] <= hi``;
    Humanoid-v5: ``lo < qpos[2] < hi``.
    """
    z = tuple(float(v) for v in params["healthy_z_range"])
    if robot == "hopper":
        return HealthyRule(1, z, angle_range=tuple(params["healthy_angle_range"]),
                           state_range=tuple(params["healthy_state_range"]))
    if robot == "walker2d":
        return HealthyRule(1, z, angle_range=tuple(params["healthy_angle_range"]))
    if robot == "ant":
        return HealthyRule(2, z, inclusive=True, finite=True)
    if robot == "humanoid":
        return HealthyRule(2, z)
    raise ValueError(f"no healthy rule for robot '{robot}'")


def is_healthy(rule: HealthyRule, qpos: Any, qvel: Any, xp: Any) -> Any:
    """``rule`` applied to one state (1-D ``qpos``/``qvel``, NumPy or JAX under vmap): a bool (array)."""
    lo, hi = rule.z_range
    z = qpos[rule.z_index]
    ok = xp.logical_and(lo <= z, z <= hi) if rule.inclusive else xp.logical_and(lo < z, z < hi)
    if rule.angle_range is not None:
        a_lo, a_hi = rule.angle_range
        ok = xp.logical_and(ok, xp.logical_and(a_lo < qpos[2], qpos[2] < a_hi))
    if rule.state_range is not None:
        s_lo, s_hi = rule.state_range
        state = xp.concatenate([qpos[2:], qvel])
        ok = xp.logical_and(ok, xp.all(xp.logical_and(s_lo < state, state < s_hi)))
    if rule.finite:
        ok = xp.logical_and(ok, xp.logical_and(xp.all(xp.isfinite(qpos)), xp.all(xp.isfinite(qvel))))
    return ok


# ---------------------------------------------------------------- running metrics and the overlay
def running_metrics(steps: Any, units: Any, errors: Any, energy_wh: Any, risk_sum: Any, novelty_sum: Any,
                    pose_sum: Any, dt_s: float, xp: Any) -> tuple[Any, ...]:
    """The episode's metrics so far, in :data:`RUNNING_METRIC_KEYS` order.

    ``mpl_per_hour = units / (steps * dt / 3600)``, ``error_rate = errors / (units + errors)``,
    ``energy_kwh = energy_wh / 1000``, ``risk_score`` / ``novelty_score``: means over steps,
    ``pose_tracking``: the sum. Every ratio is 0 while its denominator is 0.
    """
    return (
        safe_div(units * (SECONDS_PER_HOUR / dt_s), steps, xp),
        safe_div(errors, units + errors, xp),
        energy_wh / WH_PER_KWH,
        safe_div(risk_sum, steps, xp),
        safe_div(novelty_sum, steps, xp),
        pose_sum,
    )


def overlay_factors(scales: Mapping[str, float], references: Mapping[str, float] | None = None) -> dict[str, float]:
    """Per-step multiplier of each overlay term: ``scale_k / reference_k`` (missing reference: 1)."""
    refs = references or {}
    return {k: float(v) / float(refs.get(k, 1.0)) for k, v in scales.items()}


def potential_coefficients(factors: Mapping[str, float], dt_s: float) -> tuple[float, ...]:
    """``J``'s coefficients on the running sums, in :func:`overlay_potential`'s argument order.

    ``J = (c_units * units + c_risk * risk_sum + c_novelty * novelty_sum) / steps
    + c_error * errors / (units + errors) + c_energy * energy_wh + c_pose * pose_sum``
    (= ``sum_k factor_k * m_k`` with ``m_k`` from :func:`running_metrics`).
    """
    f = factors
    return (
        f.get("mpl_per_hour", 0.0) * SECONDS_PER_HOUR / dt_s,
        f.get("risk_score", 0.0),
        f.get("novelty_score", 0.0),
        f.get("error_rate", 0.0),
        f.get("energy_kwh", 0.0) / WH_PER_KWH,
        f.get("pose_tracking", 0.0),
    )


def overlay_potential(coef: Sequence[float], sums: Any, xp: Any) -> Any:
    """``J(t) = sum_k factor_k * m_k(t)`` from an episode's running sums.

    ``coef``: :func:`potential_coefficients`; ``sums``: any object with the attributes ``steps``,
    ``units``, ``errors``, ``energy_wh``, ``risk_sum``, ``novelty_sum`` and ``pose_sum`` (the
    mujoco backend's ``EpisodeTally``; a namespace of traced arrays in the mjx backend). A sum
    whose coefficient is 0 is not read.
    """
    c_units, c_risk, c_novelty, c_error, c_energy, c_pose = coef
    units = sums.units
    per_step = c_units * units + c_risk * sums.risk_sum
    if c_novelty:
        per_step = per_step + c_novelty * sums.novelty_sum
    if xp is PY:  # the CPU's per-step path: safe_div's guards inline (one call per step in all)
        steps = sums.steps
        j = (per_step / steps if steps > 0 else 0.0) + c_energy * sums.energy_wh
    else:
        j = safe_div(per_step, sums.steps, xp) + c_energy * sums.energy_wh
    if c_pose:
        j = j + c_pose * sums.pose_sum
    if c_error:
        errors = sums.errors
        if xp is not PY or errors:  # no errors: the error rate is 0
            j = j + c_error * safe_div(errors, units + errors, xp)
    return j


def episode_metric(raw_episode: Mapping[str, Any], key: str) -> float:
    """The episode metric of overlay ``key`` from an episode's raw metrics (the invariant's right side)."""
    units, errors = float(raw_episode["units_completed"]), float(raw_episode["errors"])
    if key == "mpl_per_hour":
        return safe_div(units * SECONDS_PER_HOUR, float(raw_episode["episode_length_s"]), PY)
    if key == "error_rate":
        return safe_div(errors, units + errors, PY)
    if key == "energy_kwh":
        return float(raw_episode["energy_wh"]) / WH_PER_KWH
    return float(raw_episode.get(key, 0.0))
