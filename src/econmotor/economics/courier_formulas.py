"""The courier economics per control step, written once against an array namespace ``xp``.

Every formula takes ``xp``, the namespace its arguments live in, and runs the same lines in each:

- :data:`PY` — one env's figures as Python floats (the ``mujoco`` backend's metering wrapper),
- ``numpy`` — arrays on the host,
- ``jax.numpy`` — traced arrays inside the ``mjx`` backend's jitted, vmapped step,
- torch (``econ_formulas.torch_namespace()``) — Holosoma's training reward terms, on its GPU tensors.

``PY`` is not a special case inside the formulas: it is a namespace with numpy's names
(``maximum``, ``where``, ``clip``, ...) bound to the builtins and :mod:`math`, which are what a
few scalars per step call for. No robot knowledge lives here: what a step reads from a robot's
physics (its root x, tilt, actuator forces, fall rule) is worked out by the caller
(``couriers/``) and handed over as a :class:`StepReading`.

Per control step of ``dt_s`` seconds:

- units (:func:`forward_units`): ``best_x' = max(best_x, x)``; ``units += (best_x' - best_x) / leg_distance_m``
  (a high-water mark: moving back and forth earns nothing),
- energy (:func:`electrical_energy_wh`): mechanical power ``P_mech = sum_j |qfrc_actuator_j * qvel_j|`` W
  (:func:`mechanical_power_w`), the motors' winding heat ``P_heat = sum_j k_j * qfrc_actuator_j ** 2`` W
  (:func:`winding_heat_w`; ``k_j`` from the robot's card, 0 for a robot without a motor model),
  electrical ``P_el = P_mech / drivetrain_efficiency + P_heat + idle_power_w`` (:func:`electrical_power_w`),
  ``energy_wh += P_el * dt_s / 3600``,
- risk (:func:`tilt_risk`): ``clip((tilt - tilt_margin_rad) / (fall_tilt_rad - tilt_margin_rad), 0, 1)``,
- falls: a step that ends in a fall is one error,
- novelty: visit ``n`` of cell ``floor(point / novelty_bin)`` (:func:`novelty_cell`) scores
  ``n ** -0.5`` (:func:`novelty_bonus`),
- the running episode metrics (:func:`running_metrics`) and the overlay potential
  ``J = sum_k factor_k * m_k`` (:func:`overlay_potential`, the same sum regrouped on the running
  sums); a step's overlay reward is ``J(t) - J(t-1)``, so each term's episode sum is the episode
  metric of its key (:func:`episode_metric`).
"""

from __future__ import annotations

import builtins
import math
import operator
from collections.abc import Mapping
from dataclasses import dataclass
from functools import partial
from types import SimpleNamespace
from typing import Any, NamedTuple

#: the overlay keys, the fields of :class:`RunningMetrics`.
RUNNING_METRIC_KEYS = ("mpl_per_hour", "error_rate", "energy_kwh", "risk_score", "novelty_score", "pose_tracking")

SECONDS_PER_HOUR = 3600.0
WH_PER_KWH = 1000.0


def _where(condition: Any, if_true: Any, if_false: Any) -> Any:
    return if_true if condition else if_false


def _clip(x: Any, lo: float, hi: float) -> Any:
    return lo if x < lo else hi if x > hi else x


def _sum(a: Any, axis: int | None = None) -> float:
    return builtins.sum(a, 0.0)


#: ``xp`` for one env's figures as Python floats and lists of floats (the ``mujoco`` backend's
#: per-step metering): numpy's names bound to the builtins and :mod:`math`, which is what a few
#: numbers a step call for (a NumPy call on a 3-vector costs more than the arithmetic). ``abs``
#: takes a float; ``absolute``, ``multiply`` and ``sum`` go elementwise over lists
#: (``absolute`` and ``multiply`` as lazy ``map``s, which ``sum`` consumes).
PY = SimpleNamespace(maximum=max, minimum=min, abs=abs, arccos=math.acos, where=_where, clip=_clip, sum=_sum,
                     absolute=partial(map, abs), multiply=partial(map, operator.mul))


def safe_div(num: Any, den: Any, xp: Any) -> Any:
    """``num / den`` where ``den > 0``, else 0 (finite ``num`` over an infinite denominator: no
    division by zero is evaluated)."""
    return num / xp.where(den > 0, den, math.inf)


# ---------------------------------------------------------------- an episode's rate
def rate_length_s(live_s: Any, limit_s: Any, fell: Any, xp: Any) -> Any:
    """The seconds an episode's J takes its rates (legs per hour) over: the time it ran or, for an episode
    that ended in a fall, its whole time limit (the robot on the floor delivers nothing more in it).

    Without it a fall would end an episode's clock: a walker that walks one leg fast and falls before the
    dwell scores more legs per hour than one that finishes the course (one 10 m leg in 17 s is 212 legs/h;
    the G1's whole course, 3 legs in 116 s, 93), so J would pay for falling.
    """
    return xp.where(fell, xp.maximum(live_s, limit_s), live_s)


# ---------------------------------------------------------------- the per-step formulas
def forward_units(best_x: Any, x: Any, leg_distance_m: float, xp: Any) -> tuple[Any, Any]:
    """``(best_x', units gained)``: the forward high-water mark after reaching ``x`` (m), and the
    legs of ``leg_distance_m`` it moved past the previous mark: ``(max(best_x, x) - best_x) / leg``."""
    best = xp.maximum(best_x, x)
    return best, (best - best_x) / leg_distance_m


def mechanical_power_w(qfrc_actuator: Any, qvel: Any, xp: Any) -> Any:
    """``sum_j |qfrc_actuator_j * qvel_j|``, W: actuator forces (after the gear, N or N m) times dof
    velocities (m/s or rad/s), over the last axis."""
    return xp.sum(xp.absolute(xp.multiply(qfrc_actuator, qvel)), axis=-1)


def winding_heat_w(qfrc_actuator: Any, heat_coeff: Any, xp: Any) -> Any:
    """The joint motors' winding (copper) heat, W: ``P_heat = sum_j k_j * tau_j ** 2`` over the last axis.

    A joint that holds torque ``tau_j`` (N m, after the gear) draws current ``I = tau_j / (K_t G)`` through
    its windings' resistance ``R``, whether or not it moves: ``I^2 R = k_j tau_j^2`` with
    ``k_j = R / (K_t G)^2`` (W per (N m)^2). ``heat_coeff``: ``k_j`` per joint, an array of ``qfrc_actuator``'s
    namespace (the robot card's :attr:`~econmotor.robots.card.MotorModel.heat_w_per_nm2`).
    """
    return xp.sum(qfrc_actuator * qfrc_actuator * heat_coeff, axis=-1)


def electrical_power_w(mechanical_w: Any, drivetrain_efficiency: float, idle_power_w: float,
                       heat_w: Any = 0.0) -> Any:
    """Electrical W drawn for a mechanical joint power and the windings' heat:
    ``P_el = P_mech / drivetrain_efficiency + P_heat + idle_power_w`` (braking counted as dissipated:
    ``P_mech`` sums absolute joint powers; ``P_heat``: :func:`winding_heat_w`, 0 without a motor model)."""
    return mechanical_w / drivetrain_efficiency + heat_w + idle_power_w


def mechanical_from_electrical_w(electrical_w: Any, drivetrain_efficiency: float, idle_power_w: float,
                                 heat_w: Any = 0.0) -> Any:
    """The inverse of :func:`electrical_power_w`, W:
    ``P_mech = (P_el - P_heat - idle_power_w) * drivetrain_efficiency``."""
    return (electrical_w - heat_w - idle_power_w) * drivetrain_efficiency


def electrical_energy_wh(mechanical_w: Any, drivetrain_efficiency: float, idle_power_w: float,
                         dt_s: float, heat_w: Any = 0.0) -> Any:
    """Electrical Wh over one step: ``(P_mech / drivetrain_efficiency + P_heat + idle_power_w) * dt_s / 3600``."""
    return electrical_power_w(mechanical_w, drivetrain_efficiency, idle_power_w, heat_w) * (dt_s / SECONDS_PER_HOUR)


def tilt_risk(tilt_rad: Any, tilt_margin_rad: float, fall_tilt_rad: float, xp: Any) -> Any:
    """Risk in [0, 1] of a tilt from upright: ``clip((tilt - margin) / (fall_tilt - margin), 0, 1)``."""
    return xp.minimum(xp.maximum((tilt_rad - tilt_margin_rad) / (fall_tilt_rad - tilt_margin_rad), 0.0), 1.0)


def novelty_cell(point: Any, novelty_bin: float, xp: Any) -> Any:
    """The cell of a point (an array): ``floor(point / novelty_bin)`` per coordinate."""
    return xp.floor(point / novelty_bin)


def novelty_bonus(visits: Any) -> Any:
    """The bonus of the ``visits``-th visit to a cell: ``visits ** -0.5``."""
    return visits ** -0.5


# ---------------------------------------------------------------- one control step of an episode
class MeterConstants(NamedTuple):
    """The metering settings of a courier (units in the names)."""

    leg_distance_m: float
    drivetrain_efficiency: float
    idle_power_w: float
    dt_s: float  # one control step, s
    tilt_margin_rad: float
    fall_tilt_rad: float


class StepReading(NamedTuple):
    """What one control step's metering reads from the physics (the caller works it out per robot)."""

    x_m: Any  # the root's forward position after the step, m
    mechanical_w: Any  # :func:`mechanical_power_w` over the actuated dofs, W
    tilt_rad: Any  # the torso's angle from upright, rad
    fell: Any  # the step ended in a fall (bool)
    novelty_bonus: Any = 0.0  # :func:`novelty_bonus` of this step's cell
    pose_similarity: Any = 0.0  # pose tracking's similarity at this step (0 without motion clips)
    heat_w: Any = 0.0  # :func:`winding_heat_w` over the actuated dofs, W (0 without a motor model)


@dataclass
class MeterSums:
    """An episode's running sums (Python floats, or 0-d arrays of one env under ``vmap``).

    Mutable: :func:`meter_step` adds a step to it in place (under ``jit`` the fields are rebound
    to new traced arrays, so a fresh record per traced step is built from the episode's dict).
    """

    steps: Any = 0
    units: Any = 0.0
    best_x: Any = 0.0  # the forward high-water mark, m (starts at the root's x at reset)
    errors: Any = 0.0
    energy_wh: Any = 0.0
    risk_sum: Any = 0.0
    novelty_sum: Any = 0.0
    pose_sum: Any = 0.0


def meter_step(sums: MeterSums, reading: StepReading, c: MeterConstants, xp: Any) -> None:
    """Add one control step to the episode's ``sums``, in place (the formulas in the module docstring)."""
    best_x, units_gained = forward_units(sums.best_x, reading.x_m, c.leg_distance_m, xp)
    sums.steps += 1
    sums.units += units_gained
    sums.best_x = best_x
    sums.errors += reading.fell * 1.0  # a fall is one error (``fell``: a bool)
    sums.energy_wh += electrical_energy_wh(reading.mechanical_w, c.drivetrain_efficiency, c.idle_power_w, c.dt_s,
                                           reading.heat_w)
    sums.risk_sum += tilt_risk(reading.tilt_rad, c.tilt_margin_rad, c.fall_tilt_rad, xp)
    sums.novelty_sum += reading.novelty_bonus
    sums.pose_sum += reading.pose_similarity


# ---------------------------------------------------------------- running metrics and the overlay
class RunningMetrics(NamedTuple):
    """The episode's metrics so far, one per overlay key (:data:`RUNNING_METRIC_KEYS`)."""

    mpl_per_hour: Any
    error_rate: Any
    energy_kwh: Any
    risk_score: Any
    novelty_score: Any
    pose_tracking: Any


def running_metrics(sums: MeterSums, dt_s: float, xp: Any) -> RunningMetrics:
    """The metrics the episode would report if it ended now.

    ``mpl_per_hour = units / (steps * dt_s / 3600)``, ``error_rate = errors / (units + errors)``,
    ``energy_kwh = energy_wh / 1000``, ``risk_score`` / ``novelty_score``: means over steps,
    ``pose_tracking``: the sum. Every ratio is 0 while its denominator is 0.
    """
    return RunningMetrics(
        mpl_per_hour=safe_div(sums.units * (SECONDS_PER_HOUR / dt_s), sums.steps, xp),
        error_rate=safe_div(sums.errors, sums.units + sums.errors, xp),
        energy_kwh=sums.energy_wh / WH_PER_KWH,
        risk_score=safe_div(sums.risk_sum, sums.steps, xp),
        novelty_score=safe_div(sums.novelty_sum, sums.steps, xp),
        pose_tracking=sums.pose_sum,
    )


def overlay_factors(scales: Mapping[str, float], references: Mapping[str, float] | None = None) -> dict[str, float]:
    """Per-step multiplier of each overlay term: ``scale_k / reference_k`` (missing reference: 1)."""
    refs = references or {}
    return {k: float(v) / float(refs.get(k, 1.0)) for k, v in scales.items()}


class OverlayCoefficients(NamedTuple):
    """The overlay potential's coefficients on an episode's running sums (:func:`overlay_coefficients`)."""

    units: float  # factor_mpl_per_hour * 3600 / dt_s
    risk: float  # factor_risk_score
    novelty: float  # factor_novelty_score
    error: float  # factor_error_rate
    energy: float  # factor_energy_kwh / 1000 (per Wh)
    pose: float  # factor_pose_tracking


def overlay_coefficients(factors: Mapping[str, float], dt_s: float) -> OverlayCoefficients:
    """:class:`OverlayCoefficients` of the overlay ``factors`` (key -> ``scale_k / ref_k``) at control step ``dt_s``."""
    f = {k: float(v) for k, v in factors.items()}
    return OverlayCoefficients(
        units=f.get("mpl_per_hour", 0.0) * SECONDS_PER_HOUR / dt_s,
        risk=f.get("risk_score", 0.0),
        novelty=f.get("novelty_score", 0.0),
        error=f.get("error_rate", 0.0),
        energy=f.get("energy_kwh", 0.0) / WH_PER_KWH,
        pose=f.get("pose_tracking", 0.0),
    )


def overlay_potential(sums: MeterSums, c: OverlayCoefficients, xp: Any) -> Any:
    """``J = sum_k factor_k * m_k`` over :func:`running_metrics` of ``sums``, regrouped on the sums::

        J = (c.units * units + c.risk * risk_sum + c.novelty * novelty_sum) / steps
            + c.error * errors / (units + errors) + c.energy * energy_wh + c.pose * pose_sum

    (each ratio 0 while its denominator is 0, as in :func:`running_metrics`; a test holds the two equal).
    """
    per_step = safe_div(c.units * sums.units + c.risk * sums.risk_sum + c.novelty * sums.novelty_sum, sums.steps, xp)
    return (per_step + c.error * safe_div(sums.errors, sums.units + sums.errors, xp) + c.energy * sums.energy_wh
            + c.pose * sums.pose_sum)


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
