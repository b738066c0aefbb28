"""Battery economics on hand-computed examples (module docstring of economics/battery.py)."""

from __future__ import annotations

import dataclasses
import math

import pytest

from econmotor.config.task_economics import BATTERY_KEYS, TaskEconomics
from econmotor.economics import labour
from econmotor.economics.battery import BATTERY_UNITS, duty_cycle
from econmotor.economics.meter import BATTERY_METRIC_KEYS, ECON_METRIC_KEYS, EconomicMeter
from econmotor.economics.pricing import PricingPolicy, price_evaluation, price_task
from econmotor.economics.uncertainty import BATTERY_BOOTSTRAP_FIELDS, assess
from econmotor.errors import ConfigError
from econmotor.tasks import get_task, load_catalog

# The dishwashing economics of test_pricing.py (fixed costs 35000/20000 + 0.9 + 2.0 = 4.65 USD/h, pi_e 0.12)
ECON = TaskEconomics(
    wage_human_usd_per_hour=18.0, mp_human_units_per_hour=60.0, value_per_unit_usd=0.30,
    damage_cost_usd_per_error=1.0, energy_price_usd_per_kwh=0.12, robot_capex_usd=35_000.0,
    robot_lifetime_h=20_000.0, maintenance_usd_per_hour=0.9, supervision_usd_per_hour=2.0,
)
# ... on a 400 Wh battery that recharges in 1 h
BATTERY = dataclasses.replace(ECON, battery_capacity_wh=400.0, battery_recharge_h=1.0)


def test_duty_cycle_worked_example():
    # MP_r 100/h at E_r 0.1 kWh/h (100 W, 1 Wh/unit): runtime 400/100 = 4 h, 400 units per charge,
    # charging share 1 / (4 + 1) = 0.2, 100 * 0.8 = 80 units and 0.1 * 0.8 = 0.08 kWh per paid hour
    cycle = duty_cycle(BATTERY, 100.0, 0.1)
    assert cycle.battery_runtime_h == pytest.approx(4.0)
    assert cycle.battery_units_per_charge == pytest.approx(400.0)
    assert cycle.battery_charging_share == pytest.approx(0.2)
    assert cycle.mpl_units_per_paid_hour == pytest.approx(80.0)
    assert cycle.kwh_per_paid_hour == pytest.approx(0.08)
    assert set(cycle.figures()) == set(BATTERY_UNITS)
    # units per charge is capacity / Wh per unit whatever the throughput: 400 Wh / (100 W / 50 per h) = 200
    assert duty_cycle(BATTERY, 50.0, 0.1).battery_units_per_charge == pytest.approx(200.0)


def test_a_swap_time_replaces_the_recharge():
    # a 6-minute swap: share 0.1 / (4 + 0.1) = 0.02439; the 1 h recharge no longer stops the robot
    swapped = dataclasses.replace(BATTERY, battery_swap_h=0.1)
    assert swapped.battery_downtime_h == 0.1
    assert duty_cycle(swapped, 100.0, 0.1).battery_charging_share == pytest.approx(0.1 / 4.1)
    swap_only = dataclasses.replace(ECON, battery_capacity_wh=400.0, battery_swap_h=0.0)  # a hot swap
    assert duty_cycle(swap_only, 100.0, 0.1).battery_charging_share == 0.0


def test_duty_cycle_edges():
    assert duty_cycle(ECON, 100.0, 0.1) is None  # no battery
    idle = duty_cycle(BATTERY, 100.0, 0.0)  # draws nothing: never stops to charge
    assert (idle.battery_runtime_h, idle.battery_units_per_charge, idle.battery_charging_share) == (math.inf, math.inf,
                                                                                                    0.0)
    assert idle.mpl_units_per_paid_hour == 100.0
    stuck = duty_cycle(BATTERY, 0.0, 0.1)  # draws power, completes nothing
    assert stuck.battery_units_per_charge == 0.0 and stuck.battery_charging_share == pytest.approx(0.2)
    assert stuck.mpl_units_per_paid_hour == 0.0


def test_price_with_and_without_a_battery():
    # without: cost/h 4.65 + 0.12*0.1 = 4.662, unit cost 4.662/100 = 0.04662, spread 0.30 - 0.04662 = 0.25338,
    #   price 0.04662 + 0.5*0.25338 = 0.17331 USD/unit, 17.331 USD/h
    bare = price_task(ECON, 100.0, 0.04, 0.1, PricingPolicy(0.5))
    assert bare.robot_unit_cost_usd == pytest.approx(0.04662)
    assert bare.price_usd_per_unit == pytest.approx(0.17331)
    assert bare.price_usd_per_robot_hour == pytest.approx(17.331)
    # with: 80 units and 0.08 kWh per paid hour -> cost/h 4.65 + 0.12*0.08 = 4.6596,
    #   unit cost 4.6596/80 = 0.058245 (= 4.65/80 + 0.12*0.1/100), spread 0.241755,
    #   price 0.058245 + 0.5*0.241755 = 0.1791225 USD/unit, 0.1791225*80 = 14.3298 USD per paid hour
    #   implied wage (0.30 - 1.0*0.04) * 80 = 20.8 USD per paid hour
    p = price_task(BATTERY, 100.0, 0.04, 0.1, PricingPolicy(0.5))
    assert p.robot_cost_usd_per_hour == pytest.approx(4.6596)
    assert p.robot_unit_cost_usd == pytest.approx(0.058245)
    assert p.robot_unit_cost_usd == pytest.approx(4.65 / 80 + 0.12 * 0.1 / 100)
    assert p.spread_per_unit_usd == pytest.approx(0.241755)
    assert p.price_usd_per_unit == pytest.approx(0.1791225)
    assert p.price_usd_per_robot_hour == pytest.approx(14.3298)
    assert p.implied_wage_usd_per_hour == pytest.approx(20.8)
    assert p.customer_saving_usd_per_hour == pytest.approx((0.30 - 0.1791225) * 80)
    # the measured figures stay as measured; energy per unit (and per kWh) does not change
    assert (p.mpl_units_per_hour, p.energy_kwh_per_hour) == (100.0, 0.1)
    assert p.energy_productivity_units_per_kwh == bare.energy_productivity_units_per_kwh == pytest.approx(1000.0)
    assert (p.battery_runtime_h, p.battery_units_per_charge) == (pytest.approx(4.0), pytest.approx(400.0))
    assert (p.battery_charging_share, p.mpl_units_per_paid_hour) == (pytest.approx(0.2), pytest.approx(80.0))
    # a thriftier walker (0.08 kWh/h) charges less often: runtime 5 h, share 1/6, so a lower price per unit
    thrifty = price_task(BATTERY, 100.0, 0.04, 0.08, PricingPolicy(0.5))
    assert thrifty.battery_charging_share == pytest.approx(1 / 6)
    assert thrifty.robot_unit_cost_usd == pytest.approx(4.65 / (100 * 5 / 6) + 0.12 * 0.08 / 100)
    assert thrifty.price_usd_per_unit < p.price_usd_per_unit


@pytest.mark.parametrize("mpl, err, kwh", [(100.0, 0.04, 0.1), (50.0, 0.0, 0.0), (0.0, 0.0, 0.2), (90.0, 0.1, 0.05),
                                           (1e-3, 0.5, 7.0)])
def test_a_task_without_a_battery_prices_exactly_as_before(mpl, err, kwh):
    # the formulas of pricing.py's docstring, written out without the battery module: equal to the bit
    p = price_task(ECON, mpl, err, kwh, PricingPolicy(0.5))
    cost = labour.robot_cost_per_hour(ECON, kwh)
    unit = labour.robot_unit_cost(cost, mpl)
    spread = labour.spread_per_unit(ECON, unit)
    price = unit + 0.5 * max(spread, 0.0)
    assert (p.robot_cost_usd_per_hour, p.robot_unit_cost_usd, p.spread_per_unit_usd) == (cost, unit, spread)
    assert p.price_usd_per_unit == price
    if math.isfinite(price):
        assert p.price_usd_per_robot_hour == price * mpl
    assert p.implied_wage_usd_per_hour == labour.implied_wage(0.30, mpl, 1.0, err)
    assert not p.has_battery and not set(BATTERY_UNITS) & set(p.to_dict())
    # the meter too: the same keys as ever, the same unit cost
    m = EconomicMeter(ECON).summarize({"mpl_units_per_hour": mpl, "errors": 0, "episode_length_s": 3600,
                                       "energy_kwh": kwh})
    assert set(m) == set(ECON_METRIC_KEYS)
    assert m["robot_unit_cost_usd"] == labour.robot_unit_cost(labour.robot_cost_per_hour(ECON, kwh), mpl)


def test_the_meter_reports_the_battery_and_prices_as_pricing_does():
    # one hour: 100 units on 100 Wh (E_r 0.1 kWh/h, 1 Wh per unit)
    m = EconomicMeter(BATTERY).summarize({"units_completed": 100, "errors": 0, "episode_length_s": 3600,
                                          "energy_wh": 100.0})
    assert set(m) == set(ECON_METRIC_KEYS) | set(BATTERY_METRIC_KEYS)
    assert m["battery_runtime_h"] == pytest.approx(4.0)
    assert m["battery_units_per_charge"] == pytest.approx(400.0)  # 400 Wh / 1 Wh per unit
    assert m["battery_charging_share"] == pytest.approx(0.2)
    assert m["mpl_units_per_paid_hour"] == pytest.approx(80.0)
    assert m["robot_unit_cost_usd"] == pytest.approx(4.6596 / 80)
    assert m["robot_unit_cost_usd"] == price_task(BATTERY, 100.0, 0.0, 0.1).robot_unit_cost_usd


def test_evaluation_distributions_and_intervals_carry_the_battery():
    raw = [{"units_completed": 100 + 5 * i, "errors": 0, "episode_length_s": 3600, "energy_wh": 100.0 + i}
           for i in range(6)]
    meter = EconomicMeter(BATTERY)
    episodes = [meter.summarize(r) for r in raw]
    pooled = meter.summarize({"units_completed": sum(r["units_completed"] for r in raw), "errors": 0,
                              "episode_length_s": 6 * 3600, "energy_wh": sum(r["energy_wh"] for r in raw)})
    summary = price_evaluation(BATTERY, pooled, episodes)
    assert summary.aggregate.battery_runtime_h == pytest.approx(400 / (sum(r["energy_wh"] for r in raw) / 6))
    doc = summary.to_dict()
    assert doc["units"]["battery_units_per_charge"] == "units/charge"
    assert doc["distributions"]["battery_charging_share"]["n"] == 6
    unc = assess(BATTERY, episodes, summary.aggregate, resamples=200)
    for name in BATTERY_BOOTSTRAP_FIELDS:
        iv = unc.intervals[name]
        assert iv.low <= iv.point <= iv.high and iv.low < iv.high, name
    # the conservative price: the energy's upper bound charges more often, so it costs at least the point's
    assert unc.conservative.battery_charging_share >= summary.aggregate.battery_charging_share
    assert unc.conservative.robot_unit_cost_usd >= summary.aggregate.robot_unit_cost_usd
    bare = price_evaluation(ECON, EconomicMeter(ECON).summarize(raw[0]), [EconomicMeter(ECON).summarize(raw[0])])
    assert "battery_runtime_h" not in bare.to_dict()["units"] and "battery_runtime_h" not in bare.distributions
    assert not set(BATTERY_BOOTSTRAP_FIELDS) & set(assess(ECON, [EconomicMeter(ECON).summarize(raw[0])],
                                                         bare.aggregate, resamples=20).intervals)


def test_the_g1_and_t1_tasks_state_their_makers_batteries():
    g1 = get_task("humanoid_locomotion_g1").economics
    assert (g1.battery_capacity_wh, g1.battery_recharge_h, g1.battery_swap_h) == (421.2, 1.5, None)
    assert 9.0 * 46.8 == pytest.approx(421.2)  # 9000 mAh at 46.8 V rated
    assert "maker's figure" in g1.sources["battery_capacity_wh"]
    t1 = get_task("humanoid_locomotion_t1").economics
    assert t1.battery_capacity_wh == pytest.approx(10.5 * 48) and t1.battery_recharge_h == 1.5
    assert all(t1.sources[k].startswith("assumption") for k in ("battery_capacity_wh", "battery_recharge_h"))
    rows = {r["name"]: r for r in g1.parameters()}
    assert (rows["battery_capacity_wh"]["unit"], rows["battery_recharge_h"]["unit"]) == ("Wh", "h")
    assert "battery_swap_h" not in rows
    # the G1 walking 100 legs/h at 0.1 kWh/h (1 Wh per 10 m leg): 4.212 h and 421.2 legs per charge, a 1.5 h
    # recharge loses 1.5 / 5.712 = 26.3% of the paid hours; fixed costs 40000/10000 + 1.0 + 3.5 = 8.5 USD/h:
    #   unit cost 8.5 / 73.74 + 0.13*0.1/100 = 0.11540 USD per leg (0.08513 without the battery)
    p = price_task(g1, 100.0, 0.0, 0.1)
    assert p.battery_runtime_h == pytest.approx(4.212)
    assert p.battery_units_per_charge == pytest.approx(421.2)
    assert p.battery_charging_share == pytest.approx(1.5 / 5.712)
    assert p.robot_unit_cost_usd == pytest.approx(8.5 / (100 * 4.212 / 5.712) + 0.13 * 0.1 / 100)
    assert p.robot_unit_cost_usd == pytest.approx(0.11540, abs=1e-5)
    unbattery = dataclasses.replace(g1, battery_capacity_wh=None, battery_recharge_h=None)
    assert price_task(unbattery, 100.0, 0.0, 0.1).robot_unit_cost_usd == pytest.approx(0.08513)
    # tasks that state no battery have none (another G1 task included: not stated there yet)
    assert not get_task("humanoid_wbt_g1").economics.has_battery
    assert not get_task("dishwashing").economics.has_battery


def test_economics_without_a_battery_read_as_before():
    assert not set(BATTERY_KEYS) & set(ECON.to_dict())
    assert not set(BATTERY_KEYS) & {r["name"] for r in ECON.parameters()}
    assert BATTERY.to_dict()["battery_capacity_wh"] == 400.0
    assert TaskEconomics(**{k: v for k, v in BATTERY.to_dict().items()}) == BATTERY


TASK = """\
tasks:
  carrying:
    unit: "leg"
    economics:
      wage_human_usd_per_hour: {{value: 18.0, source: "survey"}}
{battery}
    backends:
      dishwashing: {{econ_preset: toy}}
"""


def _load(tmp_path, battery: str):
    path = tmp_path / "battery.yaml"
    path.write_text(TASK.format(battery=battery))
    return load_catalog([path]).get("carrying").economics, str(path)


def test_a_catalog_battery_loads_with_units_and_sources(tmp_path):
    econ, _ = _load(tmp_path, '      battery_capacity_wh: {value: 500, unit: "Wh", source: "maker"}\n'
                              '      battery_swap_h: {value: 0.05, unit: "h", source: "time study"}')
    assert (econ.battery_capacity_wh, econ.battery_recharge_h, econ.battery_swap_h) == (500.0, None, 0.05)
    assert econ.sources["battery_swap_h"] == "time study"


@pytest.mark.parametrize("battery, key, message", [
    ('      battery_capacity_wh: {value: -5, source: "x"}\n      battery_recharge_h: {value: 1, source: "x"}',
     "battery_capacity_wh.value", "must not be negative"),
    ('      battery_capacity_wh: {value: 0, source: "x"}\n      battery_recharge_h: {value: 1, source: "x"}',
     "battery_capacity_wh", "must be > 0 Wh"),
    ('      battery_capacity_wh: {value: .nan, source: "x"}\n      battery_recharge_h: {value: 1, source: "x"}',
     "battery_capacity_wh.value", "must be finite"),
    ('      battery_capacity_wh: {value: "big", source: "x"}\n      battery_recharge_h: {value: 1, source: "x"}',
     "battery_capacity_wh.value", "expected a number"),
    ('      battery_capacity_wh: {value: 500, source: "x"}',
     "battery_capacity_wh", "needs battery_recharge_h or battery_swap_h"),
    ('      battery_recharge_h: {value: 1.5, source: "x"}', "battery_recharge_h", "needs battery_capacity_wh"),
    ('      battery_swap_h: {value: 0.1, source: "x"}', "battery_swap_h", "needs battery_capacity_wh"),
    ('      battery_capacity_wh: {value: 500, source: "x"}\n      battery_recharge_h: {value: 0, source: "x"}',
     "battery_recharge_h", "must be > 0 h"),
    ('      battery_capacity_wh: {value: 500, source: "x"}\n      battery_swap_h: {value: -1, source: "x"}',
     "battery_swap_h.value", "must not be negative"),
    ('      battery_capacity_wh: {value: 0.5, unit: "kWh", source: "x"}\n'
     '      battery_recharge_h: {value: 1, source: "x"}',
     "battery_capacity_wh.unit", "unit must be 'Wh'"),
    ('      battery_capacity_wh: {value: 500}\n      battery_recharge_h: {value: 1, source: "x"}',
     "battery_capacity_wh.source", "source"),
    ('      battery_charge_h: {value: 1, source: "x"}', "economics", "battery_charge_h"),
])
def test_a_bad_battery_is_a_config_error_naming_file_and_key(tmp_path, battery, key, message):
    with pytest.raises(ConfigError) as info:
        _load(tmp_path, battery)
    err = info.value
    assert err.source == str(tmp_path / "battery.yaml")
    assert err.key.startswith("tasks.carrying.economics") and key in err.key + str(err), (err.key, str(err))
    assert message in str(err)
