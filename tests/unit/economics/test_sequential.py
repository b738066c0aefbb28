"""The sequential rule (evidence sized to the verdict) under optional stopping, checked by simulation.

Each simulated evaluation walks episodes of ``legs`` legs; each leg falls with the policy's true
fall rate and a fall ends the episode (one error). The rule judges the first ``n_k`` episodes at each
look of a :class:`SequentialPlan` with the report's own ``decide`` on the error rate's confidence sequence
(a naive rule: the exact fixed-n binomial bounds at 95% at every look), and stops at the first look that
passes or certainly fails.
"""

from __future__ import annotations

import numpy as np
import pytest

from econmotor.config.acceptance import Acceptance
from econmotor.economics.pricing import PricingPolicy, price_task
from econmotor.economics.sequential_rule import CONTINUE, FAIL, PASS, SequentialPlan, look_outcome
from econmotor.economics.uncertainty import (
    Evidence,
    Interval,
    Uncertainty,
    clopper_pearson,
    decide,
    error_rate_sequence,
)
from econmotor.errors import ConfigError
from econmotor.tasks import get_task

LIMIT = 0.01  # the G1 walkers' accepted fall rate
ACCEPT = Acceptance(max_error_rate=LIMIT, min_units_per_hour=0.0, error_name="fall")
PRICE = price_task(get_task("humanoid_locomotion_g1").economics, 90.0, LIMIT, 0.1, PricingPolicy())


def counts_uncertainty(errors: float, attempted: float, confidence: float, naive: bool = False) -> Uncertainty:
    """What ``assess`` gives the verdict for a fall count at a sequential look (the error rate's confidence
    sequence; ``naive``: the exact fixed-n bounds at ``confidence``); throughput fine."""
    bounds = clopper_pearson if naive else lambda k, n, c: error_rate_sequence(k, n, c, LIMIT)
    low, high = bounds(errors, attempted, confidence)
    intervals = {"error_rate": Interval(errors / attempted, low, high, "Clopper-Pearson exact binomial"),
                 "mpl_units_per_hour": Interval(90.0, 80.0, 100.0, "given")}
    evidence = Evidence(episodes=1, units_attempted=attempted, units_completed=attempted - errors, errors=errors,
                        episodes_with_errors=int(errors > 0), robot_hours=1.0)
    return Uncertainty(confidence, evidence, intervals, PRICE, 0, 0)  # decide reads no price


def simulate(plan: SequentialPlan, fall_rate: float, runs: int, legs: int, seed: int,
             confidence: float | None = None) -> tuple[float, float]:
    """(share of runs judged deployable, mean episodes used) of ``runs`` simulated sequential evaluations.
    ``confidence``: judge every look by the exact fixed-n bounds at it (a naive rule)."""
    rng = np.random.default_rng(seed)
    conf = 0.95 if confidence is None else confidence
    passes, used = 0, 0
    for _ in range(runs):
        # legs walked before the first fall: geometric; a fall ends the episode with one error
        first_fall = rng.geometric(fall_rate, size=plan.max_episodes)
        falls = (first_fall <= legs).astype(float)
        attempted = np.where(falls > 0, first_fall, legs).astype(float)
        outcome, n = CONTINUE, 0
        for n in plan.looks:
            k, att = float(falls[:n].sum()), float(attempted[:n].sum())
            unc = counts_uncertainty(k, att, conf, naive=confidence is not None)
            outcome, _ = look_outcome(ACCEPT, unc, decide(ACCEPT, unc, 0.01, "10 m leg"))
            if outcome != CONTINUE:
                break
        passes += outcome == PASS
        used += n
    return passes / runs, used / runs


def test_a_policy_at_the_limit_is_judged_deployable_at_most_5_percent_of_the_time():
    plan = SequentialPlan(batch=40, max_episodes=640)
    rate, _ = simulate(plan, LIMIT, runs=2000, legs=3, seed=1)
    assert rate <= 0.05
    # the same looks, each judged at 95% without spending: optional stopping inflates false passes
    naive, _ = simulate(plan, LIMIT, runs=1000, legs=3, seed=1, confidence=0.95)
    assert naive > 0.05 and naive > 2 * rate


def test_a_policy_far_inside_the_limit_stops_early_and_one_far_outside_fails_early():
    plan = SequentialPlan(batch=20, max_episodes=640)
    rate, episodes = simulate(plan, LIMIT / 20, runs=500, legs=3, seed=2)
    # 0 falls in 324 legs pass (108 episodes: the look at 120); at most 1 fall in about 700 legs
    assert rate > 0.9 and episodes < 200
    rate, episodes = simulate(plan, 0.2, runs=500, legs=3, seed=3)
    assert rate == 0 and episodes < plan.looks[2]  # decided at the first looks, almost always


def test_fall_free_legs_bound_the_rate_nearly_as_tightly_as_a_fixed_count_and_at_every_look():
    # 0 falls: the sequence's bound is within 10% of the exact fixed-n bound, and decreases with every leg
    for legs in (50, 120, 324):
        exact = clopper_pearson(0, legs)[1]
        assert exact < error_rate_sequence(0, legs, 0.95, LIMIT)[1] < 1.1 * exact
    assert error_rate_sequence(0, 323, 0.95, LIMIT)[1] > LIMIT >= error_rate_sequence(0, 324, 0.95, LIMIT)[1]
    # each end holds its side: a fall moves both up, and the bounds bracket the observed rate
    low0, high0 = error_rate_sequence(1, 500, 0.95, LIMIT)
    low1, high1 = error_rate_sequence(2, 500, 0.95, LIMIT)
    assert 0 < low0 < low1 < 2 / 500 < high0 < high1
    assert error_rate_sequence(0, 0, 0.95, LIMIT) == (0.0, 1.0)
    assert error_rate_sequence(4, 4, 0.95, LIMIT)[1] == 1.0


def test_looks_come_after_every_batch_up_to_the_cap_and_split_the_bootstrap_alpha():
    plan = SequentialPlan(batch=20, max_episodes=110)
    assert plan.looks == (20, 40, 60, 80, 100, 110)
    assert plan.look_confidence == pytest.approx(1 - 0.05 / 6)
    assert SequentialPlan(batch=16, max_episodes=16).looks == (16,)


def test_a_certain_failure_is_told_apart_from_an_undecided_look():
    conf = 0.99
    unc = counts_uncertainty(8, 60, conf)  # 8 falls in 60 legs: certainly above 0.01
    assert look_outcome(ACCEPT, unc, decide(ACCEPT, unc, 0.01, "leg"))[0] == FAIL
    unc = counts_uncertainty(0, 60, conf)  # no fall in 60 legs: not enough to pass, nothing certain
    assert look_outcome(ACCEPT, unc, decide(ACCEPT, unc, 0.01, "leg"))[0] == CONTINUE


@pytest.mark.parametrize(("kwargs", "key"), [({"batch": 16, "max_episodes": 8}, "below one evaluation batch"),
                                             ({"batch": 16, "max_episodes": -5}, "below one evaluation batch"),
                                             ({"batch": 16, "max_wall_s": -1.0}, "positive number of seconds"),
                                             ({"batch": 0}, "must be >= 1")])
def test_a_plan_that_cannot_run_is_a_config_error(kwargs, key):
    with pytest.raises(ConfigError, match=key):
        SequentialPlan(**kwargs)


def test_the_sequence_bounds_every_count_a_look_can_meet():
    # fractional legs: almost every attempted unit an error leaves no rate below 1 excluded
    assert error_rate_sequence(1, 1.01, 0.95, 0.05)[1] == 1.0
    assert error_rate_sequence(0.5, 0.5001, 0.95, 0.05)[1] == 1.0
    for k in (0.0, 0.3, 1.0, 2.0, 7.5):
        for n in (k + 0.001, k + 0.4, k + 3.0, k + 50.0, k + 5000.0):
            low, high = error_rate_sequence(k, n, 0.95, 0.05)
            assert 0.0 <= low <= k / n <= high <= 1.0


def mixture_bounds(k: float, n: float, rate: float, confidence: float = 0.95) -> tuple[float, float]:
    """The confidence sequence's ends computed from its definition, by numerical integration rather than the
    closed form: a rate p is excluded once the mixture of likelihood ratios, the integral of
    q^k (1-q)^(n-k) / (p^k (1-p)^(n-k)) over the mixing distribution of q, reaches 1 / alpha. The upper end's
    mixture: half on q = 0 (which adds nothing once k > 0), half Beta(1, b) with mean rate / 4; the lower
    end's: Beta(1, b) with mean 4 rate (at most 1/2)."""
    from scipy.integrate import quad
    from scipy.optimize import brentq
    from scipy.stats import beta

    def log_mixture(b: float, weight: float) -> float:
        peak = k / n  # integrate q^k (1-q)^(n-k) scaled by its maximum, so the integrand is at most 1
        log_peak = k * np.log(peak) + (n - k) * np.log1p(-peak)
        integrand = lambda q: np.exp(k * np.log(q) + (n - k) * np.log1p(-q) - log_peak) * beta.pdf(q, 1.0, b)
        value, _ = quad(integrand, 0.0, 1.0, points=[peak], limit=200, epsabs=0.0, epsrel=1e-10)
        return np.log(weight * value) + log_peak

    def excluded(log_mix: float):
        return lambda p: log_mix - (k * np.log(p) + (n - k) * np.log1p(-p)) - np.log(1.0 / (1.0 - confidence))

    up = excluded(log_mixture(1.0 / (rate / 4.0) - 1.0, 0.5))
    low = excluded(log_mixture(1.0 / min(4 * rate, 0.5) - 1.0, 1.0))
    return brentq(low, 1e-12, k / n, xtol=1e-14), brentq(up, k / n, 1.0 - 1e-12, xtol=1e-14)


@pytest.mark.parametrize(("k", "n", "rate"),
                         [(1, 81, 0.05), (3, 120, 0.05), (2, 500, 0.01), (30, 100, 0.05), (10, 40, 0.2)])
def test_the_sequence_is_the_mixture_it_is_defined_by(k, n, rate):
    assert error_rate_sequence(k, n, 0.95, rate) == pytest.approx(mixture_bounds(k, n, rate), rel=1e-6)
    assert error_rate_sequence(k, n) == error_rate_sequence(k, n, 0.95, 0.05)  # the default rate: 0.05


def test_one_clean_unit_bounds_the_rate_below_one():
    assert 0.0 == error_rate_sequence(0, 1)[0] and error_rate_sequence(0, 1)[1] < 1.0
    assert clopper_pearson(0, 1) == (0.0, pytest.approx(0.95))
    assert clopper_pearson(1, 10)[0] == pytest.approx(1.0 - 0.95 ** 0.1)  # one error: Beta(1, 10)'s 5% quantile
