"""Intervals and the deployability verdict, checked against values computed by hand."""

from __future__ import annotations

import math

import pytest

from econmotor.config.acceptance import Acceptance
from econmotor.config.task_economics import TaskEconomics
from econmotor.economics.pricing import PricingPolicy, price_evaluation, price_task
from econmotor.economics.sequential_rule import CONTINUE, FAIL, PASS, SEQUENTIAL_METHOD, SequentialPlan, look_outcome
from econmotor.economics.uncertainty import (
    Evidence,
    Interval,
    Uncertainty,
    assess,
    clopper_pearson,
    counted,
    decide,
    judge,
    percent,
)
from econmotor.errors import ConfigError
from econmotor.motor_backend.results import summarize_episodes
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
                              "looks": [16, 32, 48, 64], "look_confidence": pytest.approx(1 - 0.1 / 4),
                              "method": SEQUENTIAL_METHOD}


def _judged(errors: float, attempted: float, mpl: tuple[float, float, float], confidence: float = 0.95,
            episodes: int = 4, episodes_with_errors: int = 0) -> Uncertainty:
    """An assessment with the error rate's exact bounds and a given throughput interval (point, low, high)."""
    low, high = clopper_pearson(errors, attempted, confidence)
    intervals = {"error_rate": Interval(errors / attempted, low, high, "Clopper-Pearson exact binomial"),
                 "mpl_units_per_hour": Interval(*mpl, "given")}
    evidence = Evidence(episodes, attempted, attempted - errors, errors, episodes_with_errors, 1.0)
    return Uncertainty(confidence, evidence, intervals, NOTHING, 0, 0)


HOPPER = Acceptance(max_error_rate=0.05, min_units_per_hour=100.0, error_name="fall")


def test_a_slow_clean_robot_fails_on_throughput_alone_and_says_both_checks():
    # no fall in 120 legs: upper bound 1 - 0.05**(1/120) = 0.0247 <= 0.05; throughput 60 (40..80) < 100
    unc = _judged(0, 120, (60.0, 40.0, 80.0))
    verdict = decide(HOPPER, unc, 0.002, "leg")
    assert not verdict.deployable
    assert verdict.reasons == ("95% lower bound on throughput 40 units/h vs at least 100 required",)
    err_check, mpl_check = verdict.checks[1], verdict.checks[2]
    assert (err_check["passed"], err_check["bound"], err_check["limit"]) == (True, unc.intervals["error_rate"].high,
                                                                             0.05)
    assert err_check["text"] == ("falls in none of 4 episodes (0 in 120 attempted); 95% upper bound on the fall "
                                 "rate 0.0247 vs 0.05 accepted (0.002 for a human)")
    assert (mpl_check["passed"], mpl_check["measured"], mpl_check["bound"]) == (False, 60.0, 40.0)
    # the whole interval is below 100: certainly fails, in words
    assert look_outcome(HOPPER, unc, verdict) == (FAIL, "throughput is below 100 units/h (95% upper bound 80)")
    # throughput exactly at the limit passes (>=)
    assert decide(HOPPER, _judged(0, 120, (150.0, 100.0, 200.0)), 0.002, "leg").deployable


def test_a_fall_rate_certainly_above_the_limit_is_told_with_its_lower_bound():
    unc = _judged(30, 100, (500.0, 400.0, 600.0), confidence=0.99, episodes_with_errors=3)
    verdict = decide(HOPPER, unc, 0.002, "leg")
    low = unc.intervals["error_rate"].low
    assert look_outcome(HOPPER, unc, verdict) == (FAIL, f"the fall rate is above 0.05 (99% lower bound {low:.3g})")
    assert "falls in 3 of 4 episodes (30 in 100 attempted)" in verdict.reasons[0]
    # a clean robot judged deployable passes; one not yet decided goes on with its reasons
    ok = _judged(0, 120, (500.0, 400.0, 600.0))
    assert look_outcome(HOPPER, ok, decide(HOPPER, ok, 0.002, "leg")) == (PASS, "every bound inside its limit")
    open_ = _judged(1, 30, (500.0, 400.0, 600.0))
    verdict = decide(HOPPER, open_, 0.002, "leg")
    assert look_outcome(HOPPER, open_, verdict) == (CONTINUE, "; ".join(verdict.reasons))
    # no throughput limit, or an unbounded interval: never a certain throughput failure
    free = Acceptance(max_error_rate=0.05, min_units_per_hour=0.0, error_name="fall")
    idle = _judged(1, 30, (0.0, 0.0, 0.0))
    assert look_outcome(free, idle, decide(free, idle, 0.002, "leg"))[0] == CONTINUE
    unbounded = _judged(1, 30, (50.0, 0.0, math.inf))
    assert look_outcome(HOPPER, unbounded, decide(HOPPER, unbounded, 0.002, "leg"))[0] == CONTINUE


def test_figures_in_words():
    assert (percent(0.95), percent(0.991667), percent(0.9)) == ("95%", "99.2%", "90%")
    assert (counted(1, "run"), counted(2, "run"), counted(0, "policy"), counted(1, "policy")) == (
        "1 run", "2 runs", "0 policies", "1 policy")
    verdict = decide(HOPPER, _judged(0, 1500.4, (1234.5, 1000.0, 1500.0)), 0.002, "leg")
    assert verdict.checks[0]["text"] == "1,500 units (leg) completed in 4 episodes"
    assert verdict.checks[2]["text"] == "95% lower bound on throughput 1,000 units/h vs at least 100 required"
    assert verdict.to_dict() == {"deployable": True, "label": "deployable", "reasons": [],
                                 "checks": list(verdict.checks), "acceptance": HOPPER.to_dict()}


def test_given_attempts_and_a_quarter_hour_are_pooled_as_given():
    # 10 units and 1 error in 15 attempts (4 abandoned) in 0.25 h with 50 Wh: 40 units/h, 0.2 kWh/h
    eps = [{"units_completed": 10.0, "errors": 1.0, "units_attempted": 15.0, "hours": 0.25, "energy_wh": 50.0}]
    unc = assess(ECON, eps, NOTHING)
    assert unc.evidence.units_attempted == 15.0
    assert unc.intervals["energy_kwh_per_hour"].high == pytest.approx(0.2)
    assert unc.intervals["mpl_units_per_hour"].high == pytest.approx(40.0)


def test_every_check_is_recorded_with_its_figures_and_bounds_at_the_limits_pass():
    # one unit completed (enough to have worked); the fall rate's bound exactly at the limit, given at its own
    # confidence (a confidence sequence's); the throughput's lower bound exactly at the minimum
    intervals = {"error_rate": Interval(0.0, 0.0, 0.05, "a sequence", confidence=0.9),
                 "mpl_units_per_hour": Interval(150.0, 100.0, 200.0, "given")}
    unc = Uncertainty(0.95, Evidence(4, 1.0, 1.0, 0.0, 0, 1.0), intervals, NOTHING, 0, 0)
    verdict = decide(HOPPER, unc, 0.002, "leg")
    assert verdict.deployable and verdict.reasons == ()
    assert verdict.checks == (
        {"name": "completes work", "measured": 1.0, "limit": 0.0, "passed": True,
         "text": "1 units (leg) completed in 4 episodes"},
        {"name": "error rate", "measured": 0.0, "bound": 0.05, "limit": 0.05, "passed": True,
         "text": "falls in none of 4 episodes (0 in 1 attempted); 90% upper bound on the fall rate 0.05 vs 0.05 "
                 "accepted (0.002 for a human)"},
        {"name": "throughput", "measured": 150.0, "bound": 100.0, "limit": 100.0, "passed": True,
         "text": "95% lower bound on throughput 100 units/h vs at least 100 required"})


def test_a_plan_refuses_what_cannot_run_naming_the_flag_and_what_is_allowed():
    with pytest.raises(ConfigError) as caught:
        SequentialPlan(batch=0)
    assert (caught.value.source, caught.value.key) == ("<sequential evaluation>", "batch")
    assert "must be >= 1, got 0" in str(caught.value)
    assert SequentialPlan(batch=1, max_episodes=1).looks == (1,)  # a batch of one episode is a plan
    with pytest.raises(ConfigError) as caught:
        SequentialPlan(batch=16, max_episodes=15)
    assert (caught.value.source, caught.value.key, caught.value.allowed) == ("--eval-max-episodes", None, "16 or more")
    assert "15 is below one evaluation batch (16 episodes)" in str(caught.value)
    for bad in (0.0, -1.0, math.inf, math.nan):
        with pytest.raises(ConfigError) as caught:
            SequentialPlan(batch=16, max_wall_s=bad)
        assert (caught.value.source, caught.value.key) == ("--eval-max-seconds", None)
        assert f"must be a positive number of seconds, got {bad}" in str(caught.value)
    assert SequentialPlan(batch=16, max_wall_s=0.5).max_wall_s == 0.5  # any positive time, under a second too


def test_a_look_bounds_the_error_rate_by_its_sequence_at_the_rules_limit_and_a_report_by_the_exact_bound():
    from econmotor.economics.uncertainty import ERROR_SEQUENCE_METHOD, error_rate_sequence

    task = get_task("hopper_courier")
    eps = [{"units_completed": 10.0, "errors": 1.0 if i == 0 else 0.0, "episode_length_s": 8.0, "energy_wh": 0.05}
           for i in range(8)]  # 1 error in 81 attempted
    point = price_task(task.economics, 4500.0, 1 / 81, 0.0225)
    strict = Acceptance(max_error_rate=0.01, min_units_per_hour=100.0, error_name="fall")
    fixed, _ = judge(task.economics, strict, "leg", eps, point)  # a report's judgement: the exact bound
    assert fixed.intervals["error_rate"] == Interval(1 / 81, *clopper_pearson(1, 81), "Clopper-Pearson exact binomial")
    look, verdict = judge(task.economics, strict, "leg", eps, point, confidence=0.99, sequential=True)
    assert look.intervals["error_rate"] == Interval(1 / 81, *error_rate_sequence(1, 81, 0.95, 0.01),
                                                    ERROR_SEQUENCE_METHOD, 0.95)
    assert look.intervals["error_rate"] != Interval(1 / 81, *error_rate_sequence(1, 81, 0.95), ERROR_SEQUENCE_METHOD,
                                                    0.95)  # the sequence is built for the rule's own limit
    assert look.confidence == 0.99 and "95% upper bound on the fall rate" in verdict.checks[1]["text"]


def test_a_certain_failure_is_a_bound_strictly_outside_its_limit_and_an_open_look_gives_every_reason():
    at_limit = {"error_rate": Interval(0.1, 0.05, 0.2, "a sequence", confidence=0.9),
                "mpl_units_per_hour": Interval(100.0, 50.0, 100.0, "given")}
    unc = Uncertainty(0.95, Evidence(4, 20.0, 18.0, 2.0, 2, 1.0), at_limit, NOTHING, 0, 0)
    verdict = decide(HOPPER, unc, 0.002, "leg")
    assert len(verdict.reasons) == 2  # both bounds on the wrong side of their limits, neither certainly
    assert look_outcome(HOPPER, unc, verdict) == (CONTINUE, "; ".join(verdict.reasons))
    above = dict(at_limit, error_rate=Interval(0.1, 0.0501, 0.2, "a sequence", confidence=0.9))
    unc = Uncertainty(0.95, Evidence(4, 20.0, 18.0, 2.0, 2, 1.0), above, NOTHING, 0, 0)
    assert look_outcome(HOPPER, unc, decide(HOPPER, unc, 0.002, "leg")) == (
        FAIL, "the fall rate is above 0.05 (90% lower bound 0.0501)")
    one = Acceptance(max_error_rate=0.05, min_units_per_hour=1.0, error_name="fall")
    slow = dict(at_limit, error_rate=Interval(0.0, 0.0, 0.01, "exact"), mpl_units_per_hour=Interval(0.5, 0.2, 0.9, "g"))
    unc = Uncertainty(0.95, Evidence(4, 20.0, 20.0, 0.0, 0, 1.0), slow, NOTHING, 0, 0)
    assert look_outcome(one, unc, decide(one, unc, 0.002, "leg")) == (
        FAIL, "throughput is below 1 units/h (95% upper bound 0.9)")
