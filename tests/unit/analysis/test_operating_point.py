"""Operating points (pooled figures with the report's intervals) and each objective's choice with its margin,
hand-checked on a small table under the G1 task's economics (its 421.2 Wh battery)."""

import numpy as np
import pytest

from econmotor.analysis.episode_table import EpisodeTable, RunInfo, read_episodes_jsonl, write_episodes_jsonl
from econmotor.analysis.objective_surface import preset_objectives, solve_objective_surface
from econmotor.analysis.operating_point import choices, operating_points, task_economics
from econmotor.economics.pricing import price_task
from econmotor.economics.uncertainty import clopper_pearson
from econmotor.valuation import ConstraintSet

TASK = "humanoid_locomotion_g1"


def speed_table(with_counts: bool = True) -> EpisodeTable:
    """Run "slow" (0.5 m/s): 2 + 3 legs in 0.04 h each, 5 + 6 Wh; run "fast" (1 m/s): 3 + 3 legs in 0.03 h
    each, 4 + 5 Wh, one fall in its second episode."""
    runs = [RunInfo("slow", task_id=TASK, commanded_speed_m_per_s=0.5),
            RunInfo("fast", task_id=TASK, commanded_speed_m_per_s=1.0)]
    hours, units, errors = np.array([0.04, 0.04, 0.03, 0.03]), np.array([2.0, 3, 3, 3]), np.array([0.0, 0, 0, 1])
    wh = np.array([5.0, 6, 4, 5])
    counts = {"hours": hours, "units_completed": units, "units_attempted": units + errors, "errors": errors}
    return EpisodeTable.from_arrays(runs, np.array([0, 0, 1, 1]), mpl_units_per_hour=units / hours,
                                    error_rate=errors / (units + errors), energy_wh=wh, energy_wh_per_unit=wh / units,
                                    wage_parity=np.full(4, 0.8), **(counts if with_counts else {}))


def test_each_run_is_pooled_as_a_report_pools_it_with_intervals():
    economics = task_economics([TASK, "no_such_task"])
    assert list(economics) == [TASK] and economics[TASK].battery_capacity_wh == 421.2
    slow, fast = operating_points(speed_table(), economics)
    assert (slow.run_id, slow.commanded_speed_m_per_s, fast.commanded_speed_m_per_s) == ("slow", 0.5, 1.0)
    f = slow.figures
    assert f["mpl_units_per_hour"].point == pytest.approx(5 / 0.08)
    assert f["energy_wh_per_unit"].point == pytest.approx(11 / 5)
    assert f["battery_units_per_charge"].point == pytest.approx(421.2 / (11 / 5))
    assert f["error_rate"].point == 0.0 and f["error_rate"].high == pytest.approx(clopper_pearson(0, 5)[1])
    price = price_task(economics[TASK], 5 / 0.08, 0.0, 11 / 1000 / 0.08)
    assert f["price_usd_per_unit"].point == pytest.approx(price.price_usd_per_unit)
    assert fast.figures["error_rate"].point == pytest.approx(1 / 7) and fast.evidence.errors == 1.0
    damage, low, high = fast.figures["damage_usd_per_unit"].point, *clopper_pearson(1, 7)  # 25 USD per fall
    assert (damage, fast.figures["damage_usd_per_unit"].high) == pytest.approx((25 / 7, 25 * high))
    assert fast.figures["damage_usd_per_unit"].low == pytest.approx(25 * low)
    for point in (slow, fast):
        for name, iv in point.figures.items():
            assert iv.low <= iv.point <= iv.high, name
    # the bootstrap's resamples mix the two episodes' Wh per leg: 5/2 and 6/3 bound it
    assert 2.0 <= f["energy_wh_per_unit"].low < f["energy_wh_per_unit"].high <= 2.5


def test_runs_without_counts_or_known_economics_have_no_operating_point():
    assert operating_points(speed_table(with_counts=False), task_economics([TASK])) == []
    assert operating_points(speed_table(), {}) == []


def test_each_objective_picks_a_run_with_its_j_and_margin_over_the_runner_up():
    table = speed_table()
    surface = solve_objective_surface(table, preset_objectives(["throughput", "energy_saver"]),
                                      [ConstraintSet(name="unconstrained"), ConstraintSet(name="no falls",
                                                                                          max_error_rate=0.01)])
    found = {(c.objective, c.constraint_set): c for c in choices(surface)}
    assert set(found) == {(o, s) for o in ("throughput", "energy_saver") for s in ("unconstrained", "no falls")}
    best = found[("throughput", "unconstrained")]
    u = surface.utility[:, 0]  # throughput J = 2 MPL - error rate - 0.5 Wh - 1 fall
    assert best.run_id == "fast" and best.commanded_speed_m_per_s == 1.0 and best.runner_up_run_id == "slow"
    assert best.utility.point == pytest.approx(u[1])
    assert best.margin.point == pytest.approx(u[1] - u[0]) and best.margin.low <= best.margin.point
    only = found[("throughput", "no falls")]  # the falling run is out: no runner-up
    assert only.run_id == "slow" and only.runner_up_run_id is None and only.margin is None and not only.separated


def test_a_margin_inside_the_episode_spread_is_not_separated():
    runs = [RunInfo("a", commanded_speed_m_per_s=0.6), RunInfo("b", commanded_speed_m_per_s=0.8)]
    table = EpisodeTable.from_arrays(runs, np.array([0, 0, 0, 1, 1, 1]),
                                     mpl_units_per_hour=np.array([50.0, 150, 101, 60, 140, 100]),
                                     error_rate=np.zeros(6), energy_wh=np.ones(6), energy_wh_per_unit=np.ones(6),
                                     wage_parity=np.ones(6))
    (choice,) = choices(solve_objective_surface(table, preset_objectives(["throughput"]), []))
    assert choice.run_id == "a" and choice.margin.low < 0 < choice.margin.high and not choice.separated
    assert choice.to_dict()["separated"] is False


def test_the_jsonl_export_keeps_speeds_and_counts(tmp_path):
    table = speed_table()
    back = read_episodes_jsonl(write_episodes_jsonl(table, tmp_path / "episodes.jsonl"))
    assert back.runs == table.runs and back.runs[1].commanded_speed_m_per_s == 1.0
    for name, column in table.counts.items():
        np.testing.assert_array_equal(back.counts[name], column)
