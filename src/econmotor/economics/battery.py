"""Battery economics: the hours a battery-powered robot spends charging, and what they cost per unit.

A robot that runs on a battery works until the charge is spent, then stands on its charger (or
has its pack swapped) before it works again. Its buyer pays for every hour it is deployed,
working or charging; those are the *paid* robot-hours. Symbols (DESIGN.md §3 where they exist):

- ``C``   battery capacity, Wh (``battery_capacity_wh``: the usable energy of one full charge);
- ``t_c`` hours off work per charge, h (``battery_swap_h`` when given, else ``battery_recharge_h``);
- ``E_r`` electrical energy per working hour, kWh/h (the meter's ``energy_kwh_per_hour``, i.e. the
  average electrical power while working in kW);
- ``MP_r`` good units per working hour, units/h (``mpl_units_per_hour``).

Formulas::

    runtime_h            = C / (1000 * E_r)                          h of work per charge
    energy_wh_per_unit   = 1000 * E_r / MP_r                         Wh/unit
    units_per_charge     = C / energy_wh_per_unit = runtime_h * MP_r  units
    charging_share       = t_c / (runtime_h + t_c)                   paid hours lost charging, fraction
    units_per_paid_hour  = MP_r * (1 - charging_share)               units/h
    kwh_per_paid_hour    = E_r * (1 - charging_share)                kWh/h

The price carries it through :func:`econmotor.economics.pricing.price_task`, the one place a robot is
priced: a robot with a battery is priced as one that delivers ``units_per_paid_hour`` using
``kwh_per_paid_hour`` in each paid hour. The capex share, maintenance and supervision accrue on every
paid hour (the robot and its supervisor are committed while it charges; ``robot_lifetime_h`` counts
deployed hours), the energy only on the working share (the charger puts back what the work drew), so::

    robot_unit_cost = (capex/lifetime_h + maintenance + supervision + pi_e*E_r*(1 - f)) / (MP_r*(1 - f))
                    = (capex/lifetime_h + maintenance + supervision) / (MP_r*(1 - f)) + pi_e*E_r/MP_r

with ``f = charging_share``: the fixed hourly costs spread over fewer units, the energy per unit
unchanged. Every per-hour money figure of the price (implied wage, price per robot-hour, customer
saving, break-even hours) is then per paid hour. Worked example (a Unitree G1, 421.2 Wh, 1.5 h
recharge, drawing 0.1 kWh/h at 1 Wh per 10 m leg, so MP_r = 100 legs/h): runtime 4.212 h, 421.2 legs
per charge, charging share 1.5 / 5.712 = 0.2626, 73.74 legs per paid hour.

What is not counted: charger losses (energy is priced as drawn by the robot), battery wear and
spare packs (state them in ``maintenance_usd_per_hour`` or ``robot_capex_usd``), a reserve kept in the
pack (state the usable capacity), and work that overlaps charging (a swap time says the pack charges
off the robot, spares assumed at hand). Without a battery (``battery_capacity_wh`` absent)
:func:`duty_cycle` is ``None`` and ``price_task`` prices ``MP_r`` and ``E_r`` themselves. Sources of the shipped robots'
figures are in the task catalog (``tasks/holosoma.yaml``).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Any

from econmotor.config.task_economics import TaskEconomics

#: field -> unit of :class:`DutyCycle` (the figures a report shows for a task with a battery).
BATTERY_UNITS: dict[str, str] = {
    "battery_runtime_h": "h/charge",
    "battery_units_per_charge": "units/charge",
    "battery_charging_share": "fraction of paid hours",
    "mpl_units_per_paid_hour": "units/paid h",
}


@dataclass(frozen=True)
class DutyCycle:
    """One charge cycle of a battery-powered robot (formulas in the module docstring).

    Attributes:
        battery_runtime_h: hours of work per full charge, h.
        battery_units_per_charge: good units per full charge, units.
        battery_charging_share: share of paid hours spent charging (or swapping), in [0, 1).
        mpl_units_per_paid_hour: good units per paid robot-hour, units/h.
        kwh_per_paid_hour: electrical energy per paid robot-hour, kWh/h.
    """

    battery_runtime_h: float
    battery_units_per_charge: float
    battery_charging_share: float
    mpl_units_per_paid_hour: float
    kwh_per_paid_hour: float

    def figures(self) -> dict[str, float]:
        """The figures reported beside the price (keys of :data:`BATTERY_UNITS`)."""
        return {k: v for k, v in asdict(self).items() if k in BATTERY_UNITS}

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


def duty_cycle(economics: TaskEconomics, mpl_units_per_hour: float, energy_kwh_per_hour: float) -> DutyCycle | None:
    """The charge cycle of a robot that does ``MP_r`` units/h drawing ``E_r`` kWh/h; ``None`` without a battery.

    Args:
        economics: the task's economics; its ``battery_capacity_wh`` (Wh) and ``battery_downtime_h`` (h).
        mpl_units_per_hour: ``MP_r``, good units per working hour (finite, >= 0).
        energy_kwh_per_hour: ``E_r``, electrical kWh per working hour (finite, >= 0).

    A robot that draws nothing never stops to charge (runtime ``inf``, share 0); one that completes
    nothing completes nothing per charge (0 units).
    """
    if not economics.has_battery:
        return None
    capacity_wh, downtime_h = economics.battery_capacity_wh, economics.battery_downtime_h
    assert capacity_wh is not None and downtime_h is not None  # TaskEconomics checked them
    runtime_h = capacity_wh / (1000.0 * energy_kwh_per_hour) if energy_kwh_per_hour > 0 else math.inf
    if mpl_units_per_hour <= 0:
        units_per_charge = 0.0
    else:
        units_per_charge = capacity_wh * mpl_units_per_hour / (1000.0 * energy_kwh_per_hour) \
            if energy_kwh_per_hour > 0 else math.inf
    share = downtime_h / (runtime_h + downtime_h) if math.isfinite(runtime_h) and downtime_h > 0 else 0.0
    working = 1.0 - share
    return DutyCycle(battery_runtime_h=runtime_h, battery_units_per_charge=units_per_charge,
                     battery_charging_share=share, mpl_units_per_paid_hour=mpl_units_per_hour * working,
                     kwh_per_paid_hour=energy_kwh_per_hour * working)

