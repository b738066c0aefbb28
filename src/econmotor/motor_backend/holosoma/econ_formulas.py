"""Per-step economic quantities of a legged robot, written once for numpy and torch.

The reward terms (torch tensors, inside Holosoma) and the evaluation metrics
(numpy arrays, from Holosoma's recording) call these same functions, so training
optimises exactly what evaluation measures. Only operators that numpy arrays and
torch tensors share are used (``+ - * / **``, ``abs``, ``.sum``, ``.clip``), so the
module runs on numpy 1.x, numpy 2 and torch alike.

Symbols: ``tau`` joint torques (N m), ``qd`` joint velocities (rad/s), ``eta``
drivetrain efficiency (motor + gearbox + driver, dimensionless, 0 < eta <= 1),
``v`` base linear velocity in the base frame (m/s), ``c`` commanded planar
velocity in the base frame (m/s), ``L`` metres of travel per unit of work,
``q = (x, y, z, w)`` base orientation quaternion.
"""

from __future__ import annotations

from typing import Any

#: overlay keys with a per-step Holosoma reward term (the named keys of compile_economic_overlay).
OVERLAY_TERM_KEYS = ("mpl_per_hour", "energy_kwh", "error_rate", "risk_score", "novelty_score")
#: Below this commanded speed (m/s) the robot is asked to stand: no travel counts as progress.
MIN_COMMAND_SPEED_M_PER_S = 0.1
_EPS = 1e-8


def electrical_power_w(tau: Any, qd: Any, efficiency: float) -> Any:
    """P_elec = sum_i |tau_i * qd_i| / eta  (W), per row.

    Braking (negative mechanical power) is counted as dissipated, not regenerated:
    the G1/T1 drivers burn regenerated energy in shunt resistors.
    """
    if not 0.0 < efficiency <= 1.0:
        raise ValueError(f"drivetrain efficiency must be in (0, 1], got {efficiency}")
    return abs(tau * qd).sum(-1) / efficiency


def commanded_progress_m_per_s(v_xy: Any, c_xy: Any) -> Any:
    """Speed along the commanded direction: max(v . c / |c|, 0) if |c| >= 0.1 m/s, else 0 (m/s)."""
    c_norm = ((c_xy * c_xy).sum(-1)) ** 0.5
    along = (v_xy * c_xy).sum(-1) / (c_norm + _EPS)
    moving = c_norm >= MIN_COMMAND_SPEED_M_PER_S
    return along.clip(0.0) * moving


def tilt_risk(quat_xyzw: Any, max_tilt_cos: float) -> Any:
    """Risk in [0, 1] from base tilt: (1 - cos tilt) / (1 - cos tilt_max), clipped.

    ``1 - cos tilt = 2 (x^2 + y^2)`` for a unit quaternion, so no trigonometry is needed;
    0 upright, 1 at (or beyond) the tilt where a fall is imminent.
    """
    x, y = quat_xyzw[..., 0], quat_xyzw[..., 1]
    return (2.0 * (x * x + y * y) / (1.0 - max_tilt_cos)).clip(0.0, 1.0)


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
    power_w: Any,
    fell: Any,
    risk: Any,
    novelty: Any,
    dt_s: float,
    episode_s: float,
) -> dict[str, Any]:
    """Raw per-step rates of the overlay keys, normalised so sum_t rate_t * dt = episode metric.

    Holosoma's reward manager adds ``raw * weight * dt`` each step, so over an episode of
    the nominal length ``T = episode_s``:

    - ``mpl_per_hour``:  rate = 3600 * units/s / T  ->  sum = good units per hour
    - ``energy_kwh``:    rate = P_elec / 3.6e6      ->  sum = kWh
    - ``error_rate``:    rate = fell / dt           ->  sum = falls (one attempted leg per episode)
    - ``risk_score``:    rate = risk / T            ->  sum = mean risk
    - ``novelty_score``: rate = novelty / T         ->  sum = mean novelty
    """
    return {
        "mpl_per_hour": progress_units_per_s * (3600.0 / episode_s),
        "energy_kwh": power_w / 3.6e6,
        "error_rate": fell * (1.0 / dt_s),
        "risk_score": risk * (1.0 / episode_s),
        "novelty_score": novelty * (1.0 / episode_s),
    }


def mechanical_from_electrical_w(electrical_power_w: float, efficiency: float, idle_power_w: float) -> float:
    """The mechanical joint power behind an electrical draw: ``P_mech = (P_el - idle) * eta`` (W).

    The inverse of the couriers' ``P_el = P_mech / eta + idle``
    (:func:`econmotor.economics.courier_formulas.meter_step`): the sim-to-sim evaluation reports
    both powers from the one metered energy.
    """
    return (electrical_power_w - idle_power_w) * efficiency
