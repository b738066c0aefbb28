"""Constraint shaping on real dishwashing episodes: the step penalties telescope to the
episode-level penalty (spec §5) and, in lagrangian mode, to lambda * the episode's signed cost."""

from __future__ import annotations

import math

import numpy as np
import pytest

from econmotor.config.econ_params import EconParams
from econmotor.config.objective_profile import ObjectiveVector
from econmotor.envs.dishwashing import DishwashingEnv
from econmotor.errors import ConfigError
from econmotor.networks.econ_objective_net import identity_reward_weights
from econmotor.rl.constraint_shaping import ConstraintShaper
from econmotor.rl.lagrange import signed_costs
from econmotor.rl.shadow import ShadowRewardWrapper
from econmotor.rl.task_env import make_task_env
from econmotor.valuation import ConstraintSet, apply_constraint_penalties

#: limits the random policy violates in some episodes and meets in others
ALL_LIMITS = ConstraintSet(max_error_rate=0.12, min_wage_parity=1.3, max_energy_Wh=12.0)
BUDGET = ConstraintSet(max_error_rate=0.1, max_energy_Wh=50.0, energy_basis="per_episode")


def shaped_episode(env: DishwashingEnv, shaper: ConstraintShaper, seed: int, reward: float = 0.0):
    """Run one random-action episode; return (per-step penalties, episode summary, end report)."""
    rng = np.random.default_rng(seed)
    env.reset(seed=seed)
    penalties, done = [], False
    while not done:
        _, _, term, trunc, info = env.step(rng.uniform(0, 1, 2).astype(np.float32))
        penalties.append(reward - shaper.step_reward(reward, info["step_summary"]))
        done = term or trunc
    ep = info["episode_summary"]
    return penalties, ep, shaper.end_episode(ep)


@pytest.mark.parametrize("constraints", [ALL_LIMITS, BUDGET], ids=["per_unit", "per_episode"])
def test_penalties_of_an_episode_sum_to_the_spec_penalty_of_its_summary(constraints):
    env = DishwashingEnv(EconParams.preset("toy"), max_steps=120)
    shaper = ConstraintShaper(constraints, "penalty")
    violated = met = 0
    for seed in range(10):  # one shaper across episodes: the running state must restart
        penalties, ep, report = shaped_episode(env, shaper, seed)
        episode_violation = sum(constraints.violations(ep).values())
        assert math.isfinite(episode_violation) and ep["units_completed"] > 0
        assert sum(penalties) == pytest.approx(10.0 * episode_violation, rel=1e-6, abs=1e-9), seed
        assert sum(penalties) == pytest.approx(-apply_constraint_penalties(0.0, ep, constraints), rel=1e-6,
                                               abs=1e-9)
        assert report["violations"] == constraints.violations(ep)
        violated += episode_violation > 0
        met += report["satisfied"]
    assert violated and met  # both kinds of episode were covered


def test_penalty_is_episode_sized_not_charged_on_every_step():
    """A full shift above the error cap pays 10 * the episode's excess once, where charging
    each step's own excess (the old shaping) paid it about once per step."""
    params = EconParams.preset("toy").with_overrides({"max_error_rate_sla": 10.0, "max_catastrophic_errors": 1000})
    env = DishwashingEnv(params, max_steps=120)
    shaper = ConstraintShaper(ConstraintSet(max_error_rate=0.05), "penalty")
    env.reset(seed=0)
    penalties, per_step_levels, done = [], 0.0, False
    while not done:
        _, _, term, trunc, info = env.step(np.array([0.8, 0.3], dtype=np.float32))
        s = info["step_summary"]
        penalties.append(-shaper.step_reward(0.0, s))
        per_step_levels += 10.0 * max(0.0, s["errors"] / s["attempts"] - 0.05)
        done = term or trunc
    excess = info["episode_summary"]["error_rate_episode"] - 0.05
    assert len(penalties) == 120 and excess > 0.02
    assert sum(penalties) == pytest.approx(10.0 * excess, rel=1e-6)
    assert per_step_levels > 20 * sum(penalties)


def test_lagrangian_penalties_sum_to_lambda_times_the_episode_signed_cost():
    env = DishwashingEnv(EconParams.preset("toy"), max_steps=120)
    constraints = ConstraintSet(max_error_rate=0.05, min_wage_parity=1.3)
    shaper = ConstraintShaper(constraints, "lagrangian", lagrange_lr=10.0, lagrange_init=0.3)
    lambdas = []
    for seed in range(6):
        lam = dict(shaper.multipliers.values)  # fixed within the episode
        penalties, ep, report = shaped_episode(env, shaper, seed)
        costs = signed_costs(constraints, ep)
        assert sum(penalties) == pytest.approx(sum(lam[k] * costs[k] for k in costs), rel=1e-6, abs=1e-9)
        assert report["signed_costs"] == costs
        lambdas.append(report["multipliers"]["max_error_rate"])
    assert lambdas[-1] > 0.3  # random actions exceed a 5% error rate: the multiplier rises


def test_multiplier_starts_at_zero_rises_while_violated_and_falls_back_when_met():
    shaper = ConstraintShaper(ConstraintSet(max_error_rate=0.05), "lagrangian", lagrange_lr=10.0)
    step = {"errors": 1, "attempts": 4, "units": 3, "Wh": 0.4, "t": 1}
    assert shaper.step_reward(1.0, step) == 1.0  # lambda = 0: no shaping
    shaper.reset()
    assert shaper.end_episode({"error_rate_episode": 0.10})["multipliers"]["max_error_rate"] == pytest.approx(0.5)
    assert shaper.step_reward(1.0, step) == pytest.approx(1.0 - 0.5 * (0.25 - 0.05))
    # second step of the same episode: only the change of the running signed cost is charged
    step2 = {"errors": 0, "attempts": 4, "units": 4, "Wh": 0.4, "t": 2}
    assert shaper.step_reward(1.0, step2) == pytest.approx(1.0 - 0.5 * (1 / 8 - 1 / 4))
    values = [shaper.end_episode({"error_rate_episode": 0.02})["multipliers"]["max_error_rate"]
              for _ in range(3)]
    assert values == pytest.approx([0.2, 0.0, 0.0])


def test_per_unit_energy_without_a_good_unit_is_one_limit_of_violation_not_infinite():
    shaper = ConstraintShaper(ConstraintSet(max_energy_Wh=2.0), "penalty")
    first = shaper.step_reward(0.0, {"errors": 2, "attempts": 2, "units": 0, "Wh": 0.2, "t": 1})
    assert first == pytest.approx(-10.0 * 2.0)
    second = shaper.step_reward(0.0, {"errors": 0, "attempts": 2, "units": 2, "Wh": 0.2, "t": 2})
    assert first + second == pytest.approx(0.0)  # 0.4 Wh over 2 units: the episode meets the limit


def test_wage_constraint_needs_the_running_wage_parity():
    shaper = ConstraintShaper(ConstraintSet(min_wage_parity=0.9), "penalty")
    with pytest.raises(ConfigError, match="wage_parity_running"):
        shaper.step_reward(0.0, {"errors": 0, "attempts": 1, "units": 1, "Wh": 0.1})
    with pytest.raises(ConfigError, match="attempts"):
        shaper.step_reward(0.0, {"errors": 0})


@pytest.mark.parametrize("seed", [0, 1])
def test_mujoco_step_summaries_telescope_to_the_metered_episode_violations(seed):
    """hopper_courier: the step summary's running wage parity and counts give the same
    invariant, against the episode summary the meter builds from the raw episode."""
    constraints = ConstraintSet(max_error_rate=0.01, min_wage_parity=0.5)
    task = make_task_env("hopper_courier")
    env = ShadowRewardWrapper(task.env, economics=task.economics,
                              weights_for=identity_reward_weights,
                              objective=ObjectiveVector.from_list([1, 0, 0, 0, 0]),
                              constraints=ConstraintShaper(constraints, "penalty"))
    env.reset(seed=seed)
    env.action_space.seed(seed)
    for _ in range(task.max_episode_steps):
        _, _, terminated, truncated, info = env.step(env.action_space.sample())
        if terminated or truncated:
            break
    record = info["shadow_episode"]
    violation = sum(record["constraints"]["violations"].values())
    assert violation > 0
    assert record["legacy_sum"] - record["learner_sum"] == pytest.approx(10.0 * violation, rel=1e-6)
