import math

import pytest

from econmotor.config.task_economics import TaskEconomics
from econmotor.economics import ECON_METRIC_KEYS, EconomicMeter
from econmotor.errors import ConfigError

ECON = TaskEconomics(value_per_unit_usd=0.30)
METER = EconomicMeter(ECON)


def test_worked_example_every_metric():
    m = METER.summarize({"units_completed": 90, "errors": 10, "episode_length_s": 3600, "energy_wh": 50,
                         "risk_score": 0.2, "novelty_score": 0.1})
    assert set(m) == set(ECON_METRIC_KEYS)
    assert m["hours"] == 1.0
    assert m["mpl_units_per_hour"] == pytest.approx(90.0)
    assert m["units_attempted"] == 100
    assert m["error_rate"] == pytest.approx(0.1)
    assert m["energy_kwh"] == pytest.approx(0.05)
    assert m["energy_kwh_per_hour"] == pytest.approx(0.05)
    assert m["energy_wh_per_unit"] == pytest.approx(50 / 90)
    assert m["energy_cost_usd"] == pytest.approx(0.006)
    assert m["energy_cost_usd_per_hour"] == pytest.approx(0.006)
    assert m["implied_wage_usd_per_hour"] == pytest.approx(18.0)
    assert m["wage_parity"] == pytest.approx(1.0)
    assert m["energy_productivity_units_per_kwh"] == pytest.approx(1800.0)
    assert m["robot_cost_usd_per_hour"] == pytest.approx(4.656)
    assert m["robot_unit_cost_usd"] == pytest.approx(4.656 / 90)
    assert m["human_unit_cost_usd"] == pytest.approx(0.30)
    assert m["spread_per_unit_usd"] == pytest.approx(0.30 - 4.656 / 90)
    assert (m["risk_score"], m["novelty_score"]) == (0.2, 0.1)


def test_aliases_and_step_time():
    a = METER.summarize({"completed_units": 45, "falls": 5, "attempts": 60, "steps": 1800, "dt_s": 1.0,
                         "energy_kwh": 0.02})
    assert a["hours"] == 0.5
    assert a["mpl_units_per_hour"] == pytest.approx(90.0)
    assert a["error_rate"] == pytest.approx(5 / 60)
    assert a["energy_wh"] == pytest.approx(20.0)


def test_mpl_given_directly_or_derived_from_success():
    direct = METER.summarize({"mpl_units_per_hour": 120.0, "episode_length_s": 1800})
    assert direct["units_completed"] == pytest.approx(60.0)
    assert direct["mpl_units_per_hour"] == pytest.approx(120.0)
    # 3 successful episodes of 20 minutes each: 3 units in 1 h
    success = METER.summarize({"success": 3, "episode_length_s": 3600, "num_episodes": 3})
    assert success["mpl_units_per_hour"] == pytest.approx(3.0)
    assert success["num_episodes"] == 3


def test_no_units_gives_infinite_unit_cost():
    m = METER.summarize({"units_completed": 0, "episode_length_s": 60})
    assert m["mpl_units_per_hour"] == 0.0
    assert math.isinf(m["robot_unit_cost_usd"])


@pytest.mark.parametrize(
    "raw, key",
    [
        ({"units_completed": float("nan"), "episode_length_s": 1}, "units_completed"),
        ({"units_completed": 1, "episode_length_s": float("inf")}, "episode_length_s"),
        ({"units_completed": -1, "episode_length_s": 1}, "units_completed"),
        ({"units_completed": 1, "falls": -2, "episode_length_s": 1}, "falls"),
        ({"units_completed": 1}, "episode_length_s"),
        ({"episode_length_s": 10}, "units_completed"),
        ({"units_completed": "many", "episode_length_s": 10}, "units_completed"),
    ],
)
def test_rejects_bad_raw_metrics(raw, key):
    with pytest.raises(ConfigError) as info:
        METER.summarize(raw)
    assert info.value.key == key
    assert "raw_metrics" in str(info.value)
