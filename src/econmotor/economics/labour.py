"""Labour economics of a robot (DESIGN.md §3). Plain functions, scalars in, scalars out.

Symbols: ``p`` value per good unit (USD), ``MP_r`` good units per hour, ``e_r``
errors per attempted unit, ``c_d`` damage cost per error (USD), ``w_h`` human
wage (USD/h), ``E_r`` electrical kWh per hour, ``pi_e`` electricity price (USD/kWh).
"""

from __future__ import annotations

import math

from econmotor.config.task_economics import TaskEconomics


def mpl_units_per_hour(good_units: float, hours: float) -> float:
    """MP_r = good units / hours worked (units/h); 0 when no time has passed."""
    return good_units / hours if hours > 0 else 0.0


def error_rate(errors: float, attempted_units: float) -> float:
    """e_r = errors / attempted units; 0 when nothing was attempted."""
    return errors / attempted_units if attempted_units > 0 else 0.0


def implied_wage(value_per_unit: float, mpl: float, damage_cost: float, err_rate: float) -> float:
    """w_r = p*MP_r - c_d*e_r*MP_r (USD/h): what the robot's hour is worth net of damage."""
    return value_per_unit * mpl - damage_cost * err_rate * mpl


def wage_parity(robot_wage: float, human_wage: float) -> float:
    """w_r / w_h; 1.0 means the robot's hour is worth a human's."""
    if human_wage <= 0:
        raise ValueError(f"human wage must be > 0 for wage parity, got {human_wage}")
    return robot_wage / human_wage


def energy_productivity(mpl: float, kwh_per_hour: float) -> float:
    """EP = MP_r / E_r (units per kWh); inf for work done without energy, 0 for no work."""
    if kwh_per_hour > 0:
        return mpl / kwh_per_hour
    return math.inf if mpl > 0 else 0.0


def robot_cost_per_hour(econ: TaskEconomics, kwh_per_hour: float) -> float:
    """capex/lifetime_h + maintenance_per_h + supervision_per_h + pi_e*E_r (USD/h)."""
    return (
        econ.robot_capex_usd / econ.robot_lifetime_h
        + econ.maintenance_usd_per_hour
        + econ.supervision_usd_per_hour
        + econ.energy_price_usd_per_kwh * kwh_per_hour
    )


def robot_unit_cost(cost_per_hour: float, mpl: float) -> float:
    """robot_cost_per_h / MP_r (USD/unit); inf when the robot completes nothing."""
    return cost_per_hour / mpl if mpl > 0 else math.inf


def human_unit_cost(econ: TaskEconomics) -> float:
    """w_h / MP_h (USD/unit)."""
    return econ.wage_human_usd_per_hour / econ.mp_human_units_per_hour


def spread_per_unit(econ: TaskEconomics, robot_unit_cost_usd: float) -> float:
    """human_unit_cost - robot_unit_cost (USD/unit); positive when the robot is cheaper."""
    return human_unit_cost(econ) - robot_unit_cost_usd
