"""Task pricing: what the robot's labour costs, what it is worth, and what to charge (DESIGN.md §3).

Inputs per evaluation (aggregate, or one episode): ``MP_r`` good units per hour,
``e_r`` errors per attempted unit, ``E_r`` electrical kWh per hour, and the task's
:class:`~econmotor.config.task_economics.TaskEconomics`. Formulas (USD, hours)::

    human_unit_cost          = w_h / MP_h                                       USD/unit
    robot_cost_per_hour      = capex/lifetime_h + maintenance + supervision + pi_e*E_r   USD/h
    robot_operating_per_hour = maintenance + supervision + pi_e*E_r               USD/h (no capex)
    robot_unit_cost          = robot_cost_per_hour / MP_r                          USD/unit
    implied_wage             = p*MP_r - c_d*e_r*MP_r                               USD/h
    wage_parity              = implied_wage / w_h
    spread_per_unit          = human_unit_cost - robot_unit_cost                   USD/unit
    price_per_unit           = robot_unit_cost + s * max(spread_per_unit, 0)       USD/unit
    price_per_robot_hour     = price_per_unit * MP_r                               USD/h
    customer_saving_per_hour = (human_unit_cost - price_per_unit) * MP_r           USD/h
                             = (1 - s) * max(spread, 0) * MP_r  (when competitive)
    break_even_hours         = capex / (price_per_robot_hour - robot_operating_per_hour)   h
    damage_per_unit          = c_d * e_r                                           USD/unit
    customer_saving_after_damage_per_hour
                             = (human_unit_cost + c_d*e_h - price_per_unit - c_d*e_r) * MP_r   USD/h
    energy_productivity      = MP_r / E_r                                          units/kWh

A robot on a battery (the task's economics give ``battery_capacity_wh`` and a recharge or swap
time) loses a share ``f`` of its paid hours charging (:mod:`econmotor.economics.battery`): every
formula above then takes ``MP_r (1 - f)`` units and ``E_r (1 - f)`` kWh per paid robot-hour in place
of ``MP_r`` and ``E_r`` (``energy_productivity`` excepted: the ratio is the same), so the unit cost is
``(capex/lifetime_h + maintenance + supervision) / (MP_r (1 - f)) + pi_e*E_r/MP_r`` and every per-hour
money figure is per paid hour. :class:`TaskPrice` keeps the measured ``MP_r`` and ``E_r`` and adds the
battery's figures (runtime and units per charge, the charging share, units per paid hour); a task
without a battery has ``f = 0`` and is priced, to the bit, as the formulas above.

``s`` is the seller's share of the spread (``spread_share``, default 0.5): at 0 the
customer keeps all the saving and the robot is sold at cost; at 1 the price equals
the human's unit cost. When the robot is dearer than the human (spread <= 0) it is
not competitive: the price is its unit cost and the customer saving is negative.
Break-even hours are the operating hours after which the price's margin over
operating cost has repaid the capex (``inf`` when the margin is not positive); compare
them with ``robot_lifetime_h``. A robot that completes nothing has an infinite unit
cost and price (per unit and per hour) and saves the customer nothing (0). The formulas
themselves live in :mod:`econmotor.economics.labour`.

The unit costs count the robot's own cost only (DESIGN.md §3); damage from errors is
priced beside them: ``damage_per_unit`` is the expected damage per good unit (the
convention of the implied wage, whose damage per hour is ``c_d*e_r*MP_r``), and the
customer saving after damage compares what the customer pays per good unit, price plus
damage, with what a human costs, wage plus the human's damage ``c_d*e_h`` (who bears
the damage is the contract's business; this is the customer bearing it, as with a
human worker).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass, fields
from typing import Any

from econmotor.config.task_economics import TaskEconomics
from econmotor.economics import battery, labour
from econmotor.errors import ConfigError

#: Quantiles reported over evaluation episodes.
QUANTILES: tuple[tuple[str, float], ...] = (("p10", 0.10), ("p50", 0.50), ("p90", 0.90))


@dataclass(frozen=True)
class PricingPolicy:
    """How the spread between human and robot unit cost is shared.

    Attributes:
        spread_share: the seller's share ``s`` of the spread per unit, in [0, 1].
    """

    spread_share: float = 0.5

    def __post_init__(self) -> None:
        s = self.spread_share
        if isinstance(s, bool) or not isinstance(s, (int, float)) or not math.isfinite(s) or not 0 <= s <= 1:
            raise ConfigError("<pricing>", "spread_share", f"must be a number in [0, 1], got {s!r}", "0 <= s <= 1")


@dataclass(frozen=True)
class TaskPrice:
    """Pricing of one evaluation (aggregate or one episode); formulas in the module docstring."""

    mpl_units_per_hour: float
    error_rate: float
    energy_kwh_per_hour: float
    human_unit_cost_usd: float
    robot_cost_usd_per_hour: float
    robot_operating_cost_usd_per_hour: float
    robot_unit_cost_usd: float
    implied_wage_usd_per_hour: float
    wage_parity: float
    spread_per_unit_usd: float
    price_usd_per_unit: float
    price_usd_per_robot_hour: float
    customer_saving_usd_per_hour: float
    damage_usd_per_unit: float
    customer_saving_after_damage_usd_per_hour: float
    break_even_hours: float
    energy_productivity_units_per_kwh: float
    competitive: bool
    #: the battery's figures (:data:`econmotor.economics.battery.BATTERY_UNITS`), ``None`` without one
    battery_runtime_h: float | None = None
    battery_units_per_charge: float | None = None
    battery_charging_share: float | None = None
    mpl_units_per_paid_hour: float | None = None

    @property
    def has_battery(self) -> bool:
        return self.battery_charging_share is not None

    def to_dict(self) -> dict[str, Any]:
        """Every field; the battery's only for a robot that has one (a task without reads as before)."""
        return {k: v for k, v in asdict(self).items() if not (k in battery.BATTERY_UNITS and v is None)}


#: field -> unit, for every numeric field of :class:`TaskPrice`.
PRICE_UNITS: dict[str, str] = {
    "mpl_units_per_hour": "units/h",
    "error_rate": "errors/attempted unit",
    "energy_kwh_per_hour": "kWh/h",
    "human_unit_cost_usd": "USD/unit",
    "robot_cost_usd_per_hour": "USD/h",
    "robot_operating_cost_usd_per_hour": "USD/h",
    "robot_unit_cost_usd": "USD/unit",
    "implied_wage_usd_per_hour": "USD/h",
    "wage_parity": "ratio",
    "spread_per_unit_usd": "USD/unit",
    "price_usd_per_unit": "USD/unit",
    "price_usd_per_robot_hour": "USD/h",
    "customer_saving_usd_per_hour": "USD/h",
    "damage_usd_per_unit": "USD/unit",
    "customer_saving_after_damage_usd_per_hour": "USD/h",
    "break_even_hours": "h",
    "energy_productivity_units_per_kwh": "units/kWh",
}


def price_task(economics: TaskEconomics, mpl_units_per_hour: float, error_rate: float,
               energy_kwh_per_hour: float, policy: PricingPolicy = PricingPolicy()) -> TaskPrice:
    """Price a robot that delivers ``MP_r`` units/h at error rate ``e_r`` using ``E_r`` kWh/h (per working
    hour); a task with a battery is priced per paid hour, working or charging (module docstring)."""
    for name, value in (("mpl_units_per_hour", mpl_units_per_hour), ("error_rate", error_rate),
                        ("energy_kwh_per_hour", energy_kwh_per_hour)):
        if not math.isfinite(value) or value < 0:
            raise ConfigError("<robot metrics>", name, f"must be finite and >= 0, got {value}")
    econ = economics
    # per paid robot-hour: the measured MP_r and E_r, less the share of hours a battery spends charging
    cycle = battery.duty_cycle(econ, mpl_units_per_hour, energy_kwh_per_hour)
    mpl, kwh_per_hour = (mpl_units_per_hour, energy_kwh_per_hour) if cycle is None else (
        cycle.mpl_units_per_paid_hour, cycle.kwh_per_paid_hour)
    cost_per_hour = labour.robot_cost_per_hour(econ, kwh_per_hour)
    operating = cost_per_hour - econ.robot_capex_usd / econ.robot_lifetime_h
    unit_cost = labour.robot_unit_cost(cost_per_hour, mpl)
    human_cost = labour.human_unit_cost(econ)
    spread = labour.spread_per_unit(econ, unit_cost)
    price = unit_cost + policy.spread_share * max(spread, 0.0)
    price_per_hour = price * mpl if math.isfinite(price) else math.inf
    saving = (human_cost - price) * mpl if math.isfinite(price) else (0.0 if mpl == 0 else -math.inf)
    margin = price_per_hour - operating
    wage = labour.implied_wage(econ.value_per_unit, mpl, econ.damage_cost_usd_per_error, error_rate)
    damage = econ.damage_cost_usd_per_error * error_rate
    human_damage = econ.damage_cost_usd_per_error * econ.error_rate_human
    saving_after_damage = (human_cost + human_damage - price - damage) * mpl if math.isfinite(price) else saving
    return TaskPrice(
        mpl_units_per_hour=mpl_units_per_hour,
        error_rate=error_rate,
        energy_kwh_per_hour=energy_kwh_per_hour,
        human_unit_cost_usd=human_cost,
        robot_cost_usd_per_hour=cost_per_hour,
        robot_operating_cost_usd_per_hour=operating,
        robot_unit_cost_usd=unit_cost,
        implied_wage_usd_per_hour=wage,
        wage_parity=labour.wage_parity(wage, econ.wage_human_usd_per_hour),
        spread_per_unit_usd=spread,
        price_usd_per_unit=price,
        price_usd_per_robot_hour=price_per_hour,
        customer_saving_usd_per_hour=saving,
        damage_usd_per_unit=damage,
        customer_saving_after_damage_usd_per_hour=saving_after_damage,
        break_even_hours=econ.robot_capex_usd / margin if math.isfinite(margin) and margin > 0
        else (0.0 if econ.robot_capex_usd == 0 else math.inf),
        energy_productivity_units_per_kwh=labour.energy_productivity(mpl_units_per_hour, energy_kwh_per_hour),
        competitive=spread > 0,
        **(cycle.figures() if cycle is not None else {}),
    )


def price_from_metrics(economics: TaskEconomics, econ_metrics: Mapping[str, Any],
                       policy: PricingPolicy = PricingPolicy()) -> TaskPrice:
    """:func:`price_task` on econ metrics (``EconomicMeter.summarize`` keys)."""
    try:
        mpl = float(econ_metrics["mpl_units_per_hour"])
        err = float(econ_metrics["error_rate"])
        kwh_per_hour = float(econ_metrics["energy_kwh_per_hour"])
    except KeyError as exc:
        raise ConfigError(
            "<econ metrics>", str(exc.args[0]), "missing; expected EconomicMeter.summarize keys"
        ) from None
    return price_task(economics, mpl, err, kwh_per_hour, policy)


def quantile(values: Sequence[float], q: float) -> float:
    """Linear-interpolation quantile (numpy's default) that keeps ``inf`` instead of ``nan``."""
    ordered = sorted(float(v) for v in values)
    if not ordered:
        return math.nan
    pos = q * (len(ordered) - 1)
    lo, hi = math.floor(pos), math.ceil(pos)
    a, b = ordered[lo], ordered[hi]
    if lo == hi or a == b:
        return a
    if math.isinf(a) or math.isinf(b):  # numpy would give nan for -inf..x or inf - inf
        return a if math.isinf(a) else b
    return a + (b - a) * (pos - lo)


def distribution(values: Sequence[float]) -> dict[str, float]:
    """``{"mean", "p10", "p50", "p90", "n"}`` of ``values`` (mean is ``inf`` if any value is)."""
    vals = [float(v) for v in values]
    out = {"mean": sum(vals) / len(vals) if vals else math.nan, "n": float(len(vals))}
    out.update({name: quantile(vals, q) for name, q in QUANTILES})
    return out


@dataclass(frozen=True)
class PricingSummary:
    """Aggregate pricing of an evaluation plus its per-episode distribution.

    Attributes:
        aggregate: the price of all episodes pooled (ratios of sums: total units / total hours).
        episodes: one :class:`TaskPrice` per evaluation episode.
        distributions: field -> ``{"mean", "p10", "p50", "p90", "n"}`` over ``episodes``.
        policy: the spread share used.
    """

    aggregate: TaskPrice
    episodes: tuple[TaskPrice, ...]
    distributions: dict[str, dict[str, float]]
    policy: PricingPolicy

    def to_dict(self) -> dict[str, Any]:
        units = {**PRICE_UNITS, **(battery.BATTERY_UNITS if self.aggregate.has_battery else {})}
        return {"spread_share": self.policy.spread_share, "aggregate": self.aggregate.to_dict(),
                "distributions": self.distributions, "units": units}


def price_evaluation(economics: TaskEconomics, econ_metrics: Mapping[str, Any],
                     episode_summaries: Sequence[Mapping[str, Any]],
                     policy: PricingPolicy = PricingPolicy()) -> PricingSummary:
    """Price the aggregate econ metrics and every episode summary of one evaluation."""
    episodes = tuple(price_from_metrics(economics, ep, policy) for ep in episode_summaries)
    numeric = [f.name for f in fields(TaskPrice)
               if f.name in PRICE_UNITS or (economics.has_battery and f.name in battery.BATTERY_UNITS)]
    dists = {name: distribution([getattr(p, name) for p in episodes]) for name in numeric} if episodes else {}
    return PricingSummary(price_from_metrics(economics, econ_metrics, policy), episodes, dists, policy)


def pricing_inputs(economics: TaskEconomics, policy: PricingPolicy, measured: TaskPrice,
                   measured_source: str) -> list[dict[str, Any]]:
    """Every input of the price with its unit and source: the task's economics, the spread
    share, and the robot's measured throughput, error rate and energy per hour."""
    rows = list(economics.parameters())
    rows.append({"name": "spread_share", "value": policy.spread_share, "unit": "fraction of spread",
                 "source": "pricing policy (--spread-share)"})
    for name in ("mpl_units_per_hour", "error_rate", "energy_kwh_per_hour"):
        rows.append({"name": f"robot_{name}", "value": getattr(measured, name), "unit": PRICE_UNITS[name],
                     "source": measured_source})
    return rows
