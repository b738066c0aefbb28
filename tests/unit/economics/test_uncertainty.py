"""Intervals and the deployability verdict, checked against values computed by hand."""

from __future__ import annotations

import math

import pytest

from econmotor.config.acceptance import Acceptance
from econmotor.config.task_economics import TaskEconomics
from econmotor.economics.pricing import PricingPolicy, price_evaluation, price_task
from econmotor.economics.uncertainty import (
    SEQUENTIAL_METHOD,
    SequentialPlan,
    assess,
    clopper_pearson,
    decide,
    judge,
)
from econmotor.motor_backend.base import summarize_episodes
from econmotor.tasks import get_task


def test_zero_errors_in_nine_attempts_has_a_95_percent_upper_bound_of_0_283():
    # k = 0: the upper bound solves (1 - p)^n = 0.05, so p = 1 - 0.05**(1/n)
    low, high = clopper_pearson(0, 9)
    assert low == 0.0 and high == pytest.approx(1 - 0.05 ** (1 / 9)) and round(high, 3) == 0.283
    # k = n: the lower bound solves p^n = 0.05
    low, high = clopper_pearson(5, 5)
    assert high == 1.0 and low == pytest.approx(0.05 ** (1 / 5)) and round(low, 3) == 0.549
    # 1 in 20 (Beta quantiles): upper solves P(X <= 1) = 0.05, i.e. (1-p)^20 + 20 p (1-p)^19 = 0.05
    _, high = clopper_pearson(1, 20)
    assert (1 - high) ** 20 + 20 * high * (1 - high) ** 19 == pytest.approx(0.05)
    assert clopper_pearson(0, 0) == (0.0, 1.0)  # nothing attempted: nothing known


def _episodes(raw, task_id="hopper_courier"):
    task = get_task(task_id)
    _, econ, eps = summarize_episodes(raw, task.economics)
    return task, econ, eps


def test_bootstrap_intervals_are_seeded_contain_the_estimate_and_price_conservatively():
    raw = [{"units_completed": 1.8 + 0.1 * (i % 4), "errors": 0, "episode_length_s": 8.0, "energy_wh": 0.2}
           for i in range(20)]
    task, econ, eps = _episodes(raw)
    pricing = price_evaluation(task.economics, econ, eps)
    first = assess(task.economics, eps, pricing.aggregate, pricing.policy)
    again = assess(task.economics, eps, pricing.aggregate, pricing.policy)
    assert first.to_dict() == again.to_dict()  # same episodes, same seed -> same interval
    for iv in first.intervals.values():
        assert iv.low <= iv.point <= iv.high
    mpl = first.intervals["mpl_units_per_hour"]
    assert mpl.low < mpl.point < mpl.high  # episodes differ: a real interval
    # the conservative price is the price at the worst end of every measured input
    cons = first.conservative
    assert cons.mpl_units_per_hour == mpl.low and cons.error_rate == first.intervals["error_rate"].high
    assert cons.price_usd_per_unit > pricing.aggregate.price_usd_per_unit
    ev = first.evidence
    assert (ev.episodes, ev.errors) == (20, 0) and ev.robot_hours == pytest.approx(20 * 8 / 3600)
    assert ev.units_attempted == pytest.approx(sum(r["units_completed"] for r in raw))


def test_a_robot_that_falls_in_every_episode_is_not_deployable():
    raw = [{"units_completed": 0.3, "errors": 1, "episode_length_s": 3.0, "energy_wh": 0.05} for _ in range(5)]
    task, econ, eps = _episodes(raw)
    pricing = price_evaluation(task.economics, econ, eps)
    unc = assess(task.economics, eps, pricing.aggregate, pricing.policy)
    verdict = decide(task.acceptance, unc, task.economics.error_rate_human, task.unit)
    assert not verdict.deployable and verdict.label == "not deployable"
    # 5 falls in 6.5 attempted legs: upper bound = 95% quantile of Beta(6, 1.5) = 0.972; even the lower
    # bound (5% quantile of Beta(5, 2.5)) is far above the 0.05 accepted
    assert verdict.reasons[0] == ("falls in 5 of 5 episodes (5 in 6.5 attempted); 95% upper bound on the fall "
                                  "rate 0.972 vs 0.05 accepted (0.002 for a human)")
    assert unc.intervals["error_rate"].low > 0.05
    nothing = [{"units_completed": 0, "errors": 0, "episode_length_s": 3.0, "energy_wh": 0.0}]
    task, econ, eps = _episodes(nothing)
    pricing = price_evaluation(task.economics, econ, eps)
    verdict = decide(task.acceptance, assess(task.economics, eps, pricing.aggregate), 0.002, task.unit)
    assert not verdict.deployable and verdict.reasons == ("completed no unit (delivery leg (10 m forward)) in 1 "
                                                          "evaluation episodes",)


def test_acceptance_defaults_to_the_human_error_rate_and_the_catalog_can_set_it():
    dish = get_task("dishwashing")
    assert dish.acceptance == Acceptance(dish.economics.error_rate_human, 0.0, "error", dish.acceptance.sources)
    hopper = get_task("hopper_courier").acceptance
    assert (hopper.max_error_rate, hopper.min_units_per_hour, hopper.error_name) == (0.05, 100.0, "fall")
    assert "assumption" in hopper.sources["max_error_rate"] and not math.isnan(hopper.max_error_rate)


def test_the_default_acceptance_rule_says_where_each_limit_comes_from():
    rule = Acceptance.default_for(0.03)
    assert (rule.max_error_rate, rule.min_units_per_hour, rule.error_name) == (0.03, 0.0, "error")
    assert rule.sources == {"max_error_rate": "default: the human's error rate (error_rate_human)",
                            "min_units_per_hour": "default: any positive throughput"}
    assert rule.to_dict() == {"max_error_rate": 0.03, "min_units_per_hour": 0.0, "error_name": "error",
                              "sources": rule.sources}


ECON = TaskEconomics(value_per_unit_usd=0.30)  # dishwashing defaults: 35,000 USD over 20,000 h, 2.9 USD/h running
NOTHING = price_task(ECON, 0.0, 0.0, 0.0)  # a point below every bound, so the intervals show the bootstrap's ends


def test_episodes_are_pooled_from_hours_or_seconds_and_attempts_default_to_units_plus_errors():
    # half an hour given in hours, half an hour in seconds: 30 + 20 units, 0 + 2 errors (attempted 50 + 2),
    # 50 + 50 Wh. A resample picks the first twice (60 units/h), the second twice (40/h) or both (50/h);
    # every pool uses 0.1 kWh per hour
    eps = [{"units_completed": 30.0, "hours": 0.5, "energy_wh": 50.0},
           {"units_completed": 20.0, "errors": 2.0, "episode_length_s": 1800.0, "energy_wh": 50.0}]
    unc = assess(ECON, eps, NOTHING)
    ev = unc.evidence
    assert (ev.episodes, ev.units_completed, ev.units_attempted, ev.errors) == (2, 50.0, 52.0, 2.0)
    assert ev.episodes_with_errors == 1 and ev.robot_hours == pytest.approx(1.0)
    assert unc.intervals["mpl_units_per_hour"].high == pytest.approx(60.0)  # a resample of the first twice
    assert unc.intervals["energy_kwh_per_hour"].high == pytest.approx(0.1)
    lo, hi = clopper_pearson(2, 52)
    assert (unc.intervals["error_rate"].low, unc.intervals["error_rate"].high) == (lo, hi)
    assert unc.intervals["error_rate"].method == "Clopper-Pearson exact binomial"
    assert unc.intervals["mpl_units_per_hour"].method == "bootstrap over 2 episodes, 2000 resamples, seed 20240601"
    doc = unc.to_dict()
    assert doc["confidence"] == 0.95 and doc["interval_coverage"] == pytest.approx(0.90)
    assert (doc["resamples"], doc["seed"]) == (2000, 20240601)
    assert doc["evidence"]["errors"] == 2.0 and doc["conservative"] == unc.conservative.to_dict()
    assert doc["intervals"]["error_rate"]["high"] == hi
    # the conservative price: the worst ends of throughput, error rate and energy (0.1 kWh/h, not the point's 0)
    assert unc.conservative.energy_kwh_per_hour == pytest.approx(0.1) and unc.conservative.error_rate == hi


def test_a_zero_length_episode_uses_no_energy_per_hour():
    unc = assess(ECON, [{"units_completed": 0.0, "episode_length_s": 0.0, "energy_wh": 0.0}], NOTHING)
    assert unc.intervals["energy_kwh_per_hour"].high == 0.0 and unc.intervals["mpl_units_per_hour"].high == 0.0


def test_resamples_that_complete_nothing_make_the_unit_cost_bound_infinite_and_the_conservative_mpl_zero():
    # two episodes, one with no unit: a quarter of the resamples pick it twice and complete nothing
    eps = [{"units_completed": 0.0, "episode_length_s": 1800.0}, {"units_completed": 30.0, "episode_length_s": 1800.0}]
    point = price_task(ECON, 30.0, 0.0, 0.0)
    unc = assess(ECON, eps, point)
    assert unc.intervals["robot_unit_cost_usd"].high == math.inf  # not nan: the quantile keeps inf
    assert unc.intervals["mpl_units_per_hour"].low == 0.0
    assert unc.conservative.mpl_units_per_hour == 0.0 and unc.conservative.price_usd_per_unit == math.inf


def test_no_episode_gives_no_bootstrap_interval_and_prices_the_worst_case():
    unc = assess(ECON, [], NOTHING)
    for name, iv in unc.intervals.items():
        if name != "error_rate":
            assert iv.point == getattr(NOTHING, name) and math.isnan(iv.low) and math.isnan(iv.high)
            assert iv.method == "bootstrap over 0 episodes, 2000 resamples, seed 20240601"
    assert (unc.intervals["error_rate"].low, unc.intervals["error_rate"].high) == (0.0, 1.0)
    assert unc.conservative.mpl_units_per_hour == 0.0 and unc.conservative.error_rate == 1.0


def test_the_policy_prices_every_resample_and_the_conservative_price():
    # seller's share 0: every price is the robot's unit cost, in every resample and at the worst ends
    eps = [{"units_completed": 30.0 + i, "episode_length_s": 1800.0, "energy_wh": 10.0} for i in range(5)]
    point = price_task(ECON, 64.0, 0.0, 0.02, PricingPolicy(0.0))
    unc = assess(ECON, eps, point, PricingPolicy(0.0))
    price, cost = unc.intervals["price_usd_per_unit"], unc.intervals["robot_unit_cost_usd"]
    assert (price.low, price.high) == (cost.low, cost.high)
    assert unc.conservative.price_usd_per_unit == unc.conservative.robot_unit_cost_usd


def test_judge_words_the_verdict_in_the_tasks_unit():
    task = get_task("hopper_courier")
    eps = [{"units_completed": 2.0, "episode_length_s": 8.0, "energy_wh": 0.05}] * 3
    point = price_task(task.economics, 900.0, 0.0, 0.0225)
    unc, verdict = judge(task.economics, task.acceptance, "leg", eps, point)
    assert unc.confidence == 0.95 and unc.evidence.episodes == 3
    assert verdict.checks[0]["text"] == "6 units (leg) completed in 3 episodes"


def test_a_plan_records_its_schedule_and_method():
    plan = SequentialPlan(batch=16, max_episodes=64, max_wall_s=60.0, confidence=0.9)
    assert plan.to_dict() == {"batch": 16, "max_episodes": 64, "max_wall_s": 60.0, "confidence": 0.9,
                              "looks": [16, 32, 64], "look_confidence": pytest.approx(1 - 0.1 / 3),
                              "method": SEQUENTIAL_METHOD}
