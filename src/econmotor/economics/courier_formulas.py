"""The courier economics, written once against an array namespace.

Every formula takes ``xp``, the namespace its arguments live in:

- :data:`PY` — Python floats (the ``mujoco`` backend's per-step path: no array overhead; a
  formula that runs there has a scalar branch, ``if xp is PY``),
- ``numpy`` — arrays on the host,
- ``jax.numpy`` — traced arrays inside the ``mjx`` backend's jitted, vmapped step.

The NumPy/MuJoCo path (``motor_backend/mujoco/metering.py``) and the JAX path
(``motor_backend/mjx/env.py``) both call these functions; neither keeps its own copy. A control
step's metering and overlay potential are one call, :func:`meter_step` (one Python call per
step on the CPU: the per-step cost there is mostly the code each call touches).

Per control step of ``dt_s`` seconds (see ``mujoco/metering.py`` for the story):

- units: ``best_x' = max(best_x, x)``; ``units += (best_x' - best_x) / leg_distance_m``
  (a high-water mark: moving back and forth earns nothing),
- energy: mechanical power ``sum_j |qfrc_actuator_j * qvel_j|`` W over the actuated dofs;
  electrical ``P_el = P_mech / drivetrain_efficiency + idle_power_w``; ``energy_wh += P_el * dt_s / 3600``,
- tilt: planar robots ``|root hinge angle|``; free-floating ``acos(1 - 2 (qx^2 + qy^2))``;
  risk ``clip((tilt - tilt_margin_rad) / (fall_tilt_rad - tilt_margin_rad), 0, 1)``,
- falls: Gymnasium's v5 healthy checks (:func:`healthy_rule`, :func:`is_healthy`): not healthy = one fall = one error,
- novelty: visit ``n`` of cell ``floor(obs[:novelty_dims] / novelty_bin)`` scores ``n ** -0.5``,
- running episode metrics (:func:`running_metrics`) and the overlay potential
  ``J = sum_k factor_k * m_k`` (in :func:`meter_step`); a step's overlay reward is
  ``J(t) - J(t-1)``, so each term's episode sum is the episode metric of its key.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, NamedTuple

#: overlay keys in the order :func:`running_metrics` returns them.
RUNNING_METRIC_KEYS = ("mpl_per_hour", "error_rate", "energy_kwh", "risk_score", "novelty_score", "pose_tracking")

SECONDS_PER_HOUR = 3600.0
WH_PER_KWH = 1000.0


class _PythonFloats:
    """Marks the Python-float path: a formula given ``xp=PY`` takes its scalar branch (``if xp is PY``)."""

    __slots__ = ()

    def __repr__(self) -> str:
        return "PY"


#: the namespace argument of the Python-float path (the ``mujoco`` backend's per-step work).
PY = _PythonFloats()


def safe_div(num: Any, den: Any, xp: Any) -> Any:
    """``num / den`` where ``den > 0``, else 0 (no division by zero is evaluated)."""
    if xp is PY:
        return num / den if den > 0 else 0.0
    positive = den > 0
    return xp.where(positive, num / xp.where(positive, den, 1.0), 0.0)


# ---------------------------------------------------------------- per-step metering and the overlay
class MeterConstants(NamedTuple):
    """The constants of :func:`meter_step` (build them with :func:`meter_constants`)."""

    leg_distance_m: float
    wh_per_mech_w: float  # dt_s / 3600 / drivetrain_efficiency: Wh drawn per W of mechanical power over one step
    idle_wh: float  # idle_power_w * dt_s / 3600: Wh drawn idling over one control step
    tilt_margin_rad: float
    tilt_span_rad: float  # fall_tilt_rad - tilt_margin_rad
    cos_tilt_margin: float  # cos(tilt_margin_rad) + 1e-9: a free root's cos(tilt) below it is past the margin
    free_root: bool
    coef: tuple[float, ...]  # the overlay potential's coefficients (:func:`potential_coefficients`)
    abs_dot: Callable[[Any, Any], float]  # the Python-float path's sum_j |a_j * b_j| (:func:`abs_dot_py`)


def meter_constants(leg_distance_m: float, drivetrain_efficiency: float, idle_power_w: float, dt_s: float,
                    tilt_margin_rad: float, fall_tilt_rad: float, free_root: bool,
                    factors: Mapping[str, float] | None = None, dofs: int | None = None) -> MeterConstants:
    """:class:`MeterConstants` of a courier; ``factors``: the overlay's ``scale_k / ref_k`` (None: no overlay).

    ``dofs``: the number of actuated dofs the Python-float path sums power over (None: any number).
    """
    step_hours = float(dt_s) / SECONDS_PER_HOUR  # Wh per W over one control step
    return MeterConstants(float(leg_distance_m), step_hours / float(drivetrain_efficiency),
                          float(idle_power_w) * step_hours,
                          float(tilt_margin_rad), float(fall_tilt_rad - tilt_margin_rad),
                          math.cos(float(tilt_margin_rad)) + 1e-9, bool(free_root),
                          potential_coefficients(factors or {}, float(dt_s)), abs_dot_py(dofs))


def _abs_dot_loop(a: Any, b: Any) -> float:
    total = 0.0
    for x, y in zip(a, b):  # noqa: B905 (equal lengths: the same dof span)
        total += abs(x * y)
    return total


def _written_out(name: str, params: str, body: str, namespace: dict[str, Any]) -> Callable[..., Any]:
    """``def <name>(<params>): <body>`` compiled (the Python-float path's loops written out)."""
    exec(compile(f"def {name}({params}):\n    {body}\n", f"<{name}>", "exec"), namespace)
    return namespace[name]


@functools.cache
def abs_dot_py(n: int | None) -> Callable[[Any, Any], float]:
    """``f(a, b) = sum_j |a_j * b_j|`` over Python sequences of ``n`` floats (None: of any length).

    For a known ``n`` the sum is written out, ``abs(a[0] * b[0]) + ... + abs(a[n-1] * b[n-1])``,
    and compiled once per ``n``: run between MuJoCo steps (cold caches), a Python loop over 3-17
    entries costs ~1 us more per control step than the same sum without the loop
    (``benchmarks/overlay_overhead.py``). The array namespaces compute the same sum as
    ``xp.sum(xp.abs(a * b), axis=-1)`` (:func:`meter_step`).
    """
    if n is None:
        return _abs_dot_loop
    if n < 0:
        raise ValueError(f"abs_dot_py: n must be >= 0, got {n}")
    terms = " + ".join(f"abs(a[{j}] * b[{j}])" for j in range(int(n))) or "0.0"
    return _written_out("abs_dot", "a, b", f"return {terms}", {})


#: the running sums :func:`meter_step` carries, in order (the episode's state before a step).
METER_SUMS = ("steps", "units", "best_x", "errors", "energy_wh", "risk_sum")


def meter_step(sums: Sequence[Any], qpos: Any, qfrc_actuator: Any, qvel: Any, fell: Any, novelty_sum: Any,
               pose_sum: Any, c: MeterConstants, xp: Any) -> tuple[tuple[Any, ...], Any]:
    """One control step of the courier meter and the overlay potential: ``(sums after, J(t))``.

    ``sums``: the episode's running sums before the step, in :data:`METER_SUMS` order (the
    ``mujoco`` backend: Python floats; the ``mjx`` backend: traced 0-d arrays of one env under
    vmap). ``qpos``: the root's position first (``x = qpos[0]``; planar robots: the root hinge
    angle at ``qpos[2]``; free roots: the quaternion at ``qpos[3:7]``). ``qfrc_actuator``,
    ``qvel``: over the actuated dofs (:func:`~econmotor.motor_backend.mujoco.metering.actuated_dof_span`).
    ``fell``: the step ended in a fall. ``novelty_sum`` / ``pose_sum``: the episode's sums
    including this step (their coefficients are 0 unless weighted). Per step:

    - units: ``best_x' = max(best_x, x)``; ``units += (best_x' - best_x) / leg_distance_m``,
    - energy: ``P_mech = sum_j |qfrc_actuator_j * qvel_j|`` W; ``P_el = P_mech / efficiency + idle``;
      ``energy_wh += P_el * dt_s / 3600``,
    - risk: ``risk_sum += clip((tilt - margin) / (fall_tilt - margin), 0, 1)`` with tilt
      ``|qpos[2]|`` (planar) or ``acos(1 - 2 (qx^2 + qy^2))`` (free root),
    - falls: ``errors += 1`` when ``fell``,
    - ``J = sum_k factor_k * m_k`` over the running metrics after the step (:func:`running_metrics`,
      regrouped on the sums by :func:`potential_coefficients`).

    With ``xp=PY`` the same formulas run on Python floats with their zero cases skipped (no
    progress: no units; tilt inside the margin: no risk; no errors: error rate 0).
    """
    steps, units, best_x, errors, energy_wh, risk_sum = sums
    leg_m, wh_per_mech_w, idle_wh, margin, span, cos_margin, free_root, coef, abs_dot = c
    steps = steps + 1
    x = qpos[0]
    if xp is PY:  # Python floats (memoryviews of MjData): the zero cases skipped, loops written out
        if x > best_x:
            units += (x - best_x) / leg_m
            best_x = x
        mech_w = abs_dot(qfrc_actuator, qvel)
        if free_root:
            qx, qy = qpos[4], qpos[5]
            cos_tilt = 1.0 - 2.0 * (qx * qx + qy * qy)
            if cos_tilt < cos_margin:  # past the margin (cos falls as the tilt grows)
                risk = (math.acos(cos_tilt if cos_tilt > -1.0 else -1.0) - margin) / span
                risk_sum += 0.0 if risk < 0.0 else 1.0 if risk > 1.0 else risk
        else:
            tilt = abs(qpos[2])
            if tilt > margin:
                risk = (tilt - margin) / span
                risk_sum += 1.0 if risk > 1.0 else risk
        if fell:
            errors += 1.0
    else:
        best = xp.maximum(best_x, x)
        units = units + (best - best_x) / leg_m
        best_x = best
        mech_w = xp.sum(xp.abs(qfrc_actuator * qvel), axis=-1)
        if free_root:
            qx, qy = qpos[4], qpos[5]
            tilt = xp.arccos(xp.clip(1.0 - 2.0 * (qx * qx + qy * qy), -1.0, 1.0))
        else:
            tilt = xp.abs(qpos[2])
        risk_sum = risk_sum + xp.clip((tilt - margin) / span, 0.0, 1.0)
        errors = errors + xp.where(fell, 1.0, 0.0)
    energy_wh = energy_wh + mech_w * wh_per_mech_w + idle_wh  # (P_mech / efficiency + idle) * dt_s / 3600
    # J: running_metrics' ratios regrouped (steps >= 1 here, so no guard on / steps)
    c_units, c_risk, c_novelty, c_error, c_energy, c_pose = coef
    j = ((c_units * units + c_risk * risk_sum + c_novelty * novelty_sum) / steps + c_energy * energy_wh
         + c_pose * pose_sum)
    if c_error and (xp is not PY or errors):  # no errors yet: the error rate is 0
        j = j + c_error * safe_div(errors, units + errors, xp)
    return (steps, units, best_x, errors, energy_wh, risk_sum), j


def novelty_bonus(visits: Any) -> Any:
    """The bonus of the ``visits``-th visit to a cell: ``visits ** -0.5``."""
    return visits ** -0.5


def novelty_cell(point: Any, inv_bin: float, xp: Any) -> Any:
    """The cell of a point: ``floor(point * inv_bin)`` per coordinate (``inv_bin = 1 / novelty_bin``).

    Arrays: the floored floats. ``xp=PY`` (a sequence of floats): a tuple of ints, where a NaN or
    infinite coordinate's index is None (:func:`novelty_cell_py` is the same, written out).
    """
    if xp is PY:
        return tuple(_floor_or_none(v * inv_bin) for v in point)
    return xp.floor(point * inv_bin)


def _floor_or_none(x: float) -> int | None:
    return math.floor(x) if math.isfinite(x) else None


@functools.cache
def novelty_cell_py(dims: int) -> Callable[[Sequence[float], float], tuple[int | None, ...]]:
    """``f(point, inv_bin) = novelty_cell(point[:dims], inv_bin, PY)``, written out and compiled once per ``dims``.

    ``(floor(p[0] * inv_bin), ..., floor(p[dims-1] * inv_bin))``: the ``mujoco`` backend counts a
    queued episode's cells with it, one call per step's point. A NaN or infinite coordinate makes
    ``math.floor`` raise; that point goes to :func:`novelty_cell` (the ``try`` costs nothing otherwise).
    """
    if dims < 1:
        raise ValueError(f"novelty_cell_py: dims must be >= 1, got {dims}")
    terms = ", ".join(f"floor(p[{j}] * inv_bin)" for j in range(int(dims)))
    body = (f"try:\n        return ({terms},)\n    except (ValueError, OverflowError):  # NaN or inf\n"
            f"        return novelty_cell(p[:{int(dims)}], inv_bin, PY)")
    return _written_out("novelty_cell_py", "p, inv_bin", body,
                        {"floor": math.floor, "novelty_cell": novelty_cell, "PY": PY})


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
    """``J``'s coefficients on the running sums: ``(c_units, c_risk, c_novelty, c_error, c_energy, c_pose)``.

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
