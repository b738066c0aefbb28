import math

import numpy as np
import pytest

from econmotor.config.task_economics import TaskEconomics
from econmotor.economics import ECON_METRIC_KEYS, EconomicMeter
from econmotor.economics.meter import read_raw
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


def test_a_two_hour_shift_tells_totals_from_rates():
    # 90 units, 10 errors in 2 h with 50 Wh at 0.12 USD/kWh: 45 units/h, 0.05 kWh = 0.025 kWh/h,
    # 0.006 USD of energy = 0.003 USD/h; cost/h 1.75 + 0.9 + 2.0 + 0.12*0.025 = 4.653; wage 0.3*45 - 0.1*45 = 9
    m = METER.summarize({"units_completed": 90, "errors": 10, "episode_length_s": 7200, "energy_wh": 50})
    assert (m["hours"], m["num_episodes"], m["risk_score"], m["novelty_score"]) == (2.0, 1.0, 0.0, 0.0)
    assert m["mpl_units_per_hour"] == pytest.approx(45.0) and m["error_rate"] == pytest.approx(0.1)
    assert m["energy_kwh"] == pytest.approx(0.05) and m["energy_kwh_per_hour"] == pytest.approx(0.025)
    assert m["energy_cost_usd"] == pytest.approx(0.006) and m["energy_cost_usd_per_hour"] == pytest.approx(0.003)
    assert m["energy_wh_per_unit"] == pytest.approx(50 / 90)
    assert m["energy_productivity_units_per_kwh"] == pytest.approx(1800.0)
    assert m["robot_cost_usd_per_hour"] == pytest.approx(4.653)
    assert m["robot_unit_cost_usd"] == pytest.approx(4.653 / 45)
    assert m["implied_wage_usd_per_hour"] == pytest.approx(9.0) and m["wage_parity"] == pytest.approx(0.5)
    assert m["spread_per_unit_usd"] == pytest.approx(0.30 - 4.653 / 45)


def test_no_time_no_units_and_no_energy_give_zero_rates_not_errors():
    m = METER.summarize({"units_completed": 0, "episode_length_s": 0})
    assert (m["mpl_units_per_hour"], m["energy_kwh_per_hour"], m["energy_wh"], m["errors"]) == (0.0, 0.0, 0.0, 0.0)
    assert m["energy_wh_per_unit"] == math.inf and m["units_attempted"] == 0.0


def test_numpy_counts_and_booleans_are_numbers_and_any_key_can_be_read():
    assert read_raw({"units_completed": np.int64(3)}, "units_completed") == 3.0
    assert read_raw({"success": True}, "success") == 1.0
    assert read_raw({"good_units": None, "units": 4}, "units_completed") == 4.0  # None: the next alias
    assert read_raw({"custom": 2}, "custom") == 2.0 and read_raw({}, "custom") is None


@pytest.mark.parametrize("raw, text", [
    ({"units_completed": "many", "episode_length_s": 10},
     "eval.json: key 'units_completed': expected a number, got str"),
    ({"units_completed": 1, "time_s": math.inf}, "eval.json: key 'time_s': must be finite, got inf"),
    ({"units_completed": 1, "episode_length_s": -2.0},
     "eval.json: key 'episode_length_s': must not be negative, got -2.0 (allowed: >= 0)"),
    ({"units_completed": 1, "steps": 10},
     "eval.json: key 'episode_length_s': no time worked: give episode_length_s or episode_length_steps and "
     "control_dt_s"),
    ({"episode_length_s": 1}, "eval.json: key 'units_completed': no throughput: give units_completed, "
                              "mpl_units_per_hour or success"),
    ([1, 2], "eval.json: expected a mapping, got list"),
])
def test_a_bad_raw_metric_is_refused_naming_its_source_key_and_what_is_allowed(raw, text):
    with pytest.raises(ConfigError) as info:
        METER.summarize(raw, source="eval.json")
    assert str(info.value) == text


def test_time_from_steps_is_steps_times_dt_and_one_unit_has_its_own_energy():
    m = METER.summarize({"units_completed": 1, "steps": 1800, "dt_s": 0.5, "energy_wh": 30})
    assert m["hours"] == 0.25 and m["energy_wh_per_unit"] == 30.0


def test_a_bad_value_names_raw_metrics_when_the_caller_names_no_source():
    with pytest.raises(ConfigError, match=r"^raw_metrics: key 'units_completed': expected a number, got str"):
        read_raw({"units_completed": "many"}, "units_completed")
    with pytest.raises(ConfigError, match=r"^raw_metrics: key 'energy_wh': must not be negative"):
        METER.summarize({"units_completed": 1.0, "episode_length_s": 10.0, "energy_wh": -1.0})
