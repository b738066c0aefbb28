"""Intervals and the deployability verdict, checked against values computed by hand."""

from __future__ import annotations

import math

import pytest

from econmotor.config.acceptance import Acceptance
from econmotor.economics.pricing import price_evaluation
from econmotor.economics.uncertainty import assess, clopper_pearson, decide
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
