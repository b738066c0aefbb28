import math

import pytest

from econmotor.config.task_economics import TaskEconomics
from econmotor.economics import labour
from econmotor.errors import ConfigError

ECON = TaskEconomics(
    wage_human_usd_per_hour=18.0, mp_human_units_per_hour=60.0, value_per_unit_usd=0.30,
    damage_cost_usd_per_error=1.0, energy_price_usd_per_kwh=0.12, robot_capex_usd=35_000.0,
    robot_lifetime_h=20_000.0, maintenance_usd_per_hour=0.9, supervision_usd_per_hour=2.0,
)


def test_mpl_and_error_rate():
    assert labour.mpl_units_per_hour(45, 0.5) == 90.0
    assert labour.mpl_units_per_hour(10, 0.0) == 0.0
    assert labour.error_rate(10, 100) == 0.1
    assert labour.error_rate(0, 0) == 0.0


def test_implied_wage_and_parity_worked_example():
    # w_r = p*MP - c_d*e*MP = 0.30*90 - 1.0*0.1*90 = 18 USD/h -> parity 1.0
    w = labour.implied_wage(0.30, 90.0, 1.0, 0.1)
    assert w == pytest.approx(18.0)
    assert labour.wage_parity(w, 18.0) == pytest.approx(1.0)
    assert labour.wage_parity(9.0, 18.0) == pytest.approx(0.5)
    with pytest.raises(ValueError):
        labour.wage_parity(1.0, 0.0)


def test_energy_productivity():
    assert labour.energy_productivity(90.0, 0.05) == pytest.approx(1800.0)
    assert labour.energy_productivity(0.0, 0.0) == 0.0
    assert math.isinf(labour.energy_productivity(5.0, 0.0))


def test_robot_costs_worked_example():
    # 35000/20000 + 0.9 + 2.0 + 0.12*0.05 = 4.656 USD/h
    cost = labour.robot_cost_per_hour(ECON, 0.05)
    assert cost == pytest.approx(4.656)
    unit = labour.robot_unit_cost(cost, 90.0)
    assert unit == pytest.approx(4.656 / 90)
    assert math.isinf(labour.robot_unit_cost(cost, 0.0))
    assert labour.human_unit_cost(ECON) == pytest.approx(0.30)
    assert labour.spread_per_unit(ECON, unit) == pytest.approx(0.30 - 4.656 / 90)


def test_value_per_unit_defaults_to_wage_over_throughput():
    econ = TaskEconomics(wage_human_usd_per_hour=24.0, mp_human_units_per_hour=80.0)
    assert econ.value_per_unit == pytest.approx(0.30)
    rows = {r["name"]: r for r in econ.parameters()}
    assert rows["value_per_unit_usd"]["value"] == pytest.approx(0.30)
    assert "derived" in rows["value_per_unit_usd"]["source"]
    assert all(r["unit"] for r in rows.values())


@pytest.mark.parametrize("field, value", [("wage_human_usd_per_hour", -1.0), ("energy_price_usd_per_kwh", -0.1),
                                          ("robot_lifetime_h", 0.0), ("damage_cost_usd_per_error", float("nan"))])
def test_task_economics_rejects_bad_values(field, value):
    with pytest.raises(ConfigError, match=field):
        TaskEconomics(**{field: value})


def test_fractions_below_one_are_divided_not_treated_as_zero():
    """Half a unit attempted, half a unit per hour, half a dollar an hour: each still a real figure."""
    assert labour.error_rate(0.25, 0.5) == pytest.approx(0.5)
    assert labour.robot_unit_cost(2.0, 0.5) == pytest.approx(4.0)
    assert labour.energy_productivity(0.5, 0.0) == math.inf  # work done on no energy
    assert labour.energy_productivity(0.0, 0.0) == 0.0
    assert labour.wage_parity(0.25, 0.5) == pytest.approx(0.5)
    with pytest.raises(ValueError, match=r"human wage must be > 0 for wage parity, got 0"):
        labour.wage_parity(1.0, 0)
