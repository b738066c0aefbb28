"""TaskEconomics: what a task's labour is worth, with a unit and a source per number.

Formulas that use these live in :mod:`econmotor.economics.labour` (DESIGN.md §3) and, for a robot
that runs on a battery, :mod:`econmotor.economics.battery`.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from typing import Any

from econmotor.errors import ConfigError

#: field -> unit. Every number of a task's economics is one of these.
ECONOMICS_UNITS: dict[str, str] = {
    "wage_human_usd_per_hour": "USD/h",
    "mp_human_units_per_hour": "units/h",
    "error_rate_human": "errors/attempted unit",
    "value_per_unit_usd": "USD/unit",
    "damage_cost_usd_per_error": "USD/error",
    "energy_price_usd_per_kwh": "USD/kWh",
    "robot_capex_usd": "USD",
    "robot_lifetime_h": "h",
    "maintenance_usd_per_hour": "USD/h",
    "supervision_usd_per_hour": "USD/h",
    "battery_capacity_wh": "Wh",
    "battery_recharge_h": "h",
    "battery_swap_h": "h",
}

#: The battery's keys: optional (a task without them is priced as a robot that never stops to charge);
#: a capacity needs a recharge or a swap time, and either time needs a capacity.
BATTERY_KEYS: tuple[str, ...] = ("battery_capacity_wh", "battery_recharge_h", "battery_swap_h")
#: Keys that may be ``None`` (absent from the catalog).
OPTIONAL_KEYS: frozenset[str] = frozenset({"value_per_unit_usd", *BATTERY_KEYS})


@dataclass(frozen=True)
class TaskEconomics:
    """Economic parameters of one task (DESIGN.md §3 names in brackets).

    Attributes:
        wage_human_usd_per_hour: human wage [w_h], USD/h.
        mp_human_units_per_hour: human throughput [MP_h], units/h.
        error_rate_human: human error rate [e_h], errors per attempted unit.
        value_per_unit_usd: value of a good unit [p], USD; ``None`` means ``w_h / MP_h``.
        damage_cost_usd_per_error: cost of one error [c_d], USD.
        energy_price_usd_per_kwh: electricity price [pi_e], USD/kWh.
        robot_capex_usd: robot purchase and integration [capex], USD.
        robot_lifetime_h: service hours over which capex is spread, h.
        maintenance_usd_per_hour: maintenance per operating hour, USD/h.
        supervision_usd_per_hour: human supervision per robot hour, USD/h.
        battery_capacity_wh: usable energy of one full charge, Wh (``None``: no battery priced).
        battery_recharge_h: hours the robot stands on its charger per full charge, h.
        battery_swap_h: hours a pack swap takes instead, h (used in place of the recharge when given:
            the spent pack charges off the robot).
        sources: field -> where the number comes from (or the rationale).
    """

    wage_human_usd_per_hour: float = 18.0
    mp_human_units_per_hour: float = 60.0
    error_rate_human: float = 0.05
    value_per_unit_usd: float | None = None
    damage_cost_usd_per_error: float = 1.0
    energy_price_usd_per_kwh: float = 0.12
    robot_capex_usd: float = 35_000.0
    robot_lifetime_h: float = 20_000.0
    maintenance_usd_per_hour: float = 0.9
    supervision_usd_per_hour: float = 2.0
    battery_capacity_wh: float | None = None
    battery_recharge_h: float | None = None
    battery_swap_h: float | None = None
    sources: dict[str, str] = field(default_factory=dict, compare=False, hash=False)

    def __post_init__(self) -> None:
        for name in ECONOMICS_UNITS:
            value = getattr(self, name)
            if value is None and name in OPTIONAL_KEYS:
                continue
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
                raise ConfigError("<task_economics>", name, f"must be a finite number, got {value!r}")
            if value < 0:
                raise ConfigError("<task_economics>", name, f"must not be negative, got {value}", ">= 0")
        for name in ("mp_human_units_per_hour", "robot_lifetime_h"):
            if getattr(self, name) <= 0:
                raise ConfigError("<task_economics>", name, "must be > 0")
        if self.error_rate_human > 1:
            raise ConfigError("<task_economics>", "error_rate_human", "must be <= 1")
        self._check_battery()

    def _check_battery(self) -> None:
        capacity, recharge, swap = self.battery_capacity_wh, self.battery_recharge_h, self.battery_swap_h
        if capacity is None:
            for name in ("battery_recharge_h", "battery_swap_h"):
                if getattr(self, name) is not None:
                    raise ConfigError("<task_economics>", name,
                                      "needs battery_capacity_wh (Wh): a charging time without a battery")
            return
        if capacity <= 0:
            raise ConfigError("<task_economics>", "battery_capacity_wh", f"must be > 0 Wh, got {capacity}")
        if recharge is None and swap is None:
            raise ConfigError("<task_economics>", "battery_capacity_wh",
                              "needs battery_recharge_h or battery_swap_h (h): how long a charge stops the robot")
        if recharge is not None and recharge <= 0:
            raise ConfigError("<task_economics>", "battery_recharge_h", f"must be > 0 h, got {recharge}")

    @property
    def has_battery(self) -> bool:
        """Whether the robot runs on a battery whose charging the price carries."""
        return self.battery_capacity_wh is not None

    @property
    def battery_downtime_h(self) -> float | None:
        """Hours off work per full charge: the swap time when given, else the recharge time (h)."""
        if not self.has_battery:
            return None
        return self.battery_swap_h if self.battery_swap_h is not None else self.battery_recharge_h

    @property
    def value_per_unit(self) -> float:
        """p: the declared value per good unit, or ``w_h / MP_h`` when absent (USD/unit)."""
        if self.value_per_unit_usd is not None:
            return self.value_per_unit_usd
        return self.wage_human_usd_per_hour / self.mp_human_units_per_hour

    def parameters(self) -> list[dict[str, Any]]:
        """Every input number with its unit and source, for reports."""
        rows = []
        for name, unit in ECONOMICS_UNITS.items():
            value = getattr(self, name)
            if value is None and name in BATTERY_KEYS:
                continue
            source = self.sources.get(name, "econmotor default")
            if name == "value_per_unit_usd" and value is None:
                value, source = self.value_per_unit, "derived: wage_human / mp_human (DESIGN.md §3)"
            rows.append({"name": name, "value": value, "unit": unit, "source": source})
        return rows

    def to_dict(self) -> dict[str, Any]:
        """Every field; the battery's only when given (a task without one reads as before)."""
        return {k: v for k, v in asdict(self).items() if not (k in BATTERY_KEYS and v is None)}
