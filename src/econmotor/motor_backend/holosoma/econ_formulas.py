"""Per-step economic quantities of a legged robot in Holosoma: the couriers' meter, read from Holosoma's tensors.

One meter per robot: a G1 trained here (Holosoma's reward terms, torch) and a G1 priced here (the
sim-to-sim evaluator, :mod:`econmotor.locomotion.env`) are metered by the same formulas,
:mod:`econmotor.economics.courier_formulas`, with the same constants (the task's locomotion
block in the catalog, ``locomotion.task.meter_settings``):

- electrical power ``P_el = sum_i |tau_i qd_i| / eta + sum_i k_i tau_i^2 + idle_power_w`` (W;
  ``cf.mechanical_power_w``, ``cf.winding_heat_w`` with the robot card's motor model, ``cf.electrical_power_w``;
  braking counted as dissipated: the G1/T1 drivers burn regenerated energy in shunt resistors),
- tilt risk ``clip((tilt - tilt_margin_rad) / (fall_tilt_rad - tilt_margin_rad), 0, 1)`` of the base's
  tilt from upright (``cf.tilt_risk`` of :func:`base_tilt_rad`).

What stays Holosoma's own: progress toward a unit (training has no course: the base velocity along
the commanded direction, :func:`commanded_progress_m_per_s`), falls (Holosoma's terminations) and
joint-space novelty (:func:`novelty_step`). The arithmetic uses only what numpy arrays and torch
tensors share, or the ``xp`` namespace the courier formulas take (``numpy``, :func:`torch_namespace`).

Symbols: ``tau`` joint torques (N m), ``qd`` joint velocities (rad/s), ``v`` base linear velocity in
the base frame (m/s), ``c`` commanded planar velocity in the base frame (m/s), ``q = (x, y, z, w)``
base orientation quaternion.
"""

from __future__ import annotations

from types import SimpleNamespace
from typing import Any

from econmotor.couriers.physics import quat_tilt_rad
from econmotor.economics import courier_formulas as cf

#: overlay keys with a per-step Holosoma reward term (the named keys of compile_economic_overlay).
OVERLAY_TERM_KEYS = ("mpl_per_hour", "energy_kwh", "error_rate", "risk_score", "novelty_score")
#: Below this commanded speed (m/s) the robot is asked to stand: no travel counts as progress.
MIN_COMMAND_SPEED_M_PER_S = 0.1
_EPS = 1e-8


def torch_namespace() -> Any:
    """``xp`` for the courier formulas on torch tensors: numpy's names bound to torch's functions
    (torch's ``maximum`` / ``minimum`` take no Python scalar, so they go through ``where``)."""
    import torch

    return SimpleNamespace(maximum=lambda a, b: torch.where(a >= b, a, b),
                           minimum=lambda a, b: torch.where(a <= b, a, b), where=torch.where, clip=torch.clip,
                           arccos=torch.arccos, abs=torch.abs, absolute=torch.abs, multiply=torch.multiply,
                           sum=torch.sum, floor=torch.floor)


def base_tilt_rad(quat_xyzw: Any, xp: Any) -> Any:
    """The base's tilt from upright (rad) from Holosoma's ``(x, y, z, w)`` quaternions (last axis)."""
    return quat_tilt_rad(quat_xyzw[..., 0], quat_xyzw[..., 1], xp)


def commanded_progress_m_per_s(v_xy: Any, c_xy: Any) -> Any:
    """Speed along the commanded direction: max(v . c / |c|, 0) if |c| >= 0.1 m/s, else 0 (m/s)."""
    c_norm = ((c_xy * c_xy).sum(-1)) ** 0.5
    along = (v_xy * c_xy).sum(-1) / (c_norm + _EPS)
    moving = c_norm >= MIN_COMMAND_SPEED_M_PER_S
    return along.clip(0.0) * moving


def novelty_step(q: Any, mean: Any, var: Any, rate: float) -> tuple[Any, Any, Any]:
    """Novelty of joint configuration ``q`` against running statistics, and the updated stats.

    d = mean_i (q_i - mu_i)^2 / (var_i + 1e-4);  novelty = d / (1 + d) in [0, 1).
    Then mu <- mu + rate (q - mu), var <- (1 - rate) var + rate (q - mu)^2 (an exponential
    moving estimate; ``rate`` 0.01 remembers about the last 100 steps).
    """
    diff = q - mean
    d = (diff * diff / (var + 1e-4)).sum(-1) / q.shape[-1]
    novelty = d / (1.0 + d)
    new_mean = mean + rate * diff
    new_var = (1.0 - rate) * var + rate * diff * diff
    return novelty, new_mean, new_var


def overlay_term_rates(
    *,
    progress_units_per_s: Any,
    mechanical_w: Any,
    fell: Any,
    tilt_rad: Any,
    novelty: Any,
    constants: cf.MeterConstants,
    episode_s: float,
    xp: Any,
    heat_w: Any = 0.0,
) -> dict[str, Any]:
    """Raw per-step rates of the overlay keys, normalised so sum_t rate_t * dt = episode metric.

    ``constants``: the courier meter's (:func:`econmotor.locomotion.task.meter_constants`, ``dt_s``
    the control step); ``heat_w``: the windings' heat (``cf.winding_heat_w``, 0 without a motor model).
    Holosoma's reward manager adds ``raw * weight * dt`` each step, so over an episode of the
    nominal length ``T = episode_s``:

    - ``mpl_per_hour``:  rate = 3600 * units/s / T           ->  sum = good units per hour
    - ``energy_kwh``:    rate = cf.electrical_power_w / 3.6e6 ->  sum = kWh, idle power included
    - ``error_rate``:    rate = fell / dt                    ->  sum = falls (one attempted leg per episode)
    - ``risk_score``:    rate = cf.tilt_risk / T              ->  sum = mean risk
    - ``novelty_score``: rate = novelty / T                  ->  sum = mean novelty
    """
    c = constants
    electrical_w = cf.electrical_power_w(mechanical_w, c.drivetrain_efficiency, c.idle_power_w, heat_w)
    return {
        "mpl_per_hour": progress_units_per_s * (cf.SECONDS_PER_HOUR / episode_s),
        "energy_kwh": electrical_w / (cf.SECONDS_PER_HOUR * cf.WH_PER_KWH),
        "error_rate": fell * (1.0 / c.dt_s),
        "risk_score": cf.tilt_risk(tilt_rad, c.tilt_margin_rad, c.fall_tilt_rad, xp) * (1.0 / episode_s),
        "novelty_score": novelty * (1.0 / episode_s),
    }
