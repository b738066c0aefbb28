"""The dishwashing env's rewards and summaries agree with the economics and valuation layers."""

from __future__ import annotations

import numpy as np
import pytest

from econmotor.config.econ_params import EconParams
from econmotor.economics import LegacyRewardWeights, compute_econ_reward
from econmotor.envs import DishwashingEnv
from econmotor.objectives import EconomicObjectiveSpec, compile_economic_overlay
from econmotor.valuation import build_reward_terms, combine_reward
from econmotor.valuation.reward_builder import IncrementalRewardTerms

EPISODE_METRIC_OF = {
    "mpl_per_hour": "mpl_episode",
    "energy_kwh": "energy_kwh",
    "error_rate": "error_rate_episode",
    "risk_score": "risk_score",
    "novelty_score": "novelty_score",
    "energy_kwh_per_hour": "energy_kwh_per_hour",
    "profit_usd": "profit",
    "units_completed": "units_completed",
}


def random_episode(env: DishwashingEnv, seed: int):
    rng = np.random.default_rng(seed)
    env.reset(seed=seed)
    infos, rewards, done = [], [], False
    while not done:
        _, r, term, trunc, info = env.step(rng.uniform(0, 1, 2).astype(np.float32))
        infos.append(info)
        rewards.append(r)
        done = term or trunc
    return infos, rewards, infos[-1]["episode_summary"]


@pytest.mark.parametrize("seed", range(6))
def test_overlay_terms_sum_to_the_episode_metrics(seed):
    objective = EconomicObjectiveSpec(mpl_weight=2.0, energy_weight=50.0, error_weight=30.0,
                                      novelty_weight=0.5, risk_weight=3.0,
                                      extra_weights={"profit_usd": 0.1, "energy_kwh_per_hour": -2.0})
    refs = {"mpl_per_hour": 60.0, "error_rate": 0.05}
    env = DishwashingEnv(EconParams.preset("toy"), objective=objective, term_references=refs)
    infos, rewards, ep = random_episode(env, seed)
    for key, metric in EPISODE_METRIC_OF.items():
        total = sum(info["overlay_terms"][key] for info in infos)
        assert total == pytest.approx(ep[metric], rel=1e-9, abs=1e-12), key
    overlay = compile_economic_overlay(objective)
    expected = sum(scale * ep[EPISODE_METRIC_OF[k]] / refs.get(k, 1.0) for k, scale in overlay.items())
    assert sum(rewards) == pytest.approx(expected, rel=1e-9, abs=1e-12)
    assert ep["return"] == pytest.approx(sum(rewards))


def test_overlay_ignores_and_lists_keys_it_cannot_measure():
    env = DishwashingEnv(objective=EconomicObjectiveSpec(extra_weights={"stability_margin": -0.1}))
    assert env.ignored_overlay_keys == ("stability_margin",)


def test_legacy_reward_is_compute_econ_reward_of_the_step_summary():
    weights = LegacyRewardWeights(alpha=1.0, beta=2.0, gamma=0.3)
    infos, rewards, ep = random_episode(DishwashingEnv(reward_mode="legacy", legacy_weights=weights), 1)
    for info, r in zip(infos, rewards, strict=True):
        s = info["step_summary"]
        assert r == pytest.approx(compute_econ_reward(s["d_mpl"], s["error_rate_t"], s["implied_wage_t"], 18.0,
                                                      weights))
    # d_mpl telescopes to the episode MPL
    assert sum(i["step_summary"]["d_mpl"] for i in infos) == pytest.approx(ep["mpl_episode"])


def test_reward_builder_step_rewards_are_incremental_terms_of_the_step_summaries():
    vector = [1.0, 2.0, 3.0, 4.0, 0.5]
    params = EconParams.preset("toy")
    infos, rewards, ep = random_episode(DishwashingEnv(params, reward_mode="reward_builder",
                                                       objective_vector=vector), 2)
    replay = IncrementalRewardTerms()
    for info, r in zip(infos, rewards, strict=True):
        s = info["step_summary"]
        terms = replay.step(s, params)
        assert terms["r_energy"] == -s["Wh"]  # toy has no electricity price: energy term is -Wh
        assert r == pytest.approx(combine_reward(vector, terms))
    ep_terms = build_reward_terms(ep, params)
    assert ep_terms["r_mpl"] == ep["mpl_episode"]
    assert ep_terms["r_error"] == -ep["error_rate_episode"]
    assert ep_terms["r_energy"] == -ep["energy_Wh"]
    assert ep_terms["r_safety"] == (-1.0 if ep["termination_reason"] == "catastrophic_error" else 0.0)


@pytest.mark.parametrize("price", [None, 0.3])
def test_reward_builder_episode_return_is_the_episode_objective(price):
    """DESIGN §3: the step rewards of an episode sum to combine_reward(w, terms of the episode)."""
    params = EconParams.preset("toy").with_overrides({"energy_price_usd_per_kwh": price})
    vector = [1.0, 0.2, 0.1, 0.05, 0.3]
    env = DishwashingEnv(params, reward_mode="reward_builder", objective_vector=vector)
    reasons = set()
    for seed in range(12):  # the env is reused: the running terms must restart at every reset
        _, rewards, ep = random_episode(env, seed)
        reasons.add(ep["termination_reason"])
        expected = combine_reward(vector, build_reward_terms(ep, params))
        assert sum(rewards) == pytest.approx(expected, rel=1e-6), seed
        assert ep["return"] == pytest.approx(sum(rewards))
    assert len(reasons) >= 2  # failures (r_safety) and full shifts both covered
    # a full shift's return is about the episode MPL, not MPL x episode length
    _, rewards, ep = random_episode(DishwashingEnv(params, reward_mode="reward_builder",
                                                   objective_vector=[1, 0, 0, 0, 0]), 0)
    assert sum(rewards) == pytest.approx(ep["mpl_episode"], rel=1e-6)


def test_step_summary_running_wage_matches_the_episode_summary():
    infos, _, ep = random_episode(DishwashingEnv(EconParams.preset("toy")), 3)
    last = infos[-1]["step_summary"]
    assert last["error_rate_running"] == pytest.approx(ep["error_rate_episode"], rel=1e-9)
    assert last["implied_wage_running"] == pytest.approx(ep["implied_wage_usd_per_hour"], rel=1e-9)
    assert last["wage_parity_running"] == pytest.approx(ep["wage_parity"], rel=1e-9)


def test_episode_summary_economics_are_consistent():
    params = EconParams.preset("toy")
    _, _, ep = random_episode(DishwashingEnv(params), 4)
    hours = ep["episode_length_s"] / 3600
    assert ep["mpl_episode"] == pytest.approx(ep["units_completed"] / hours)
    assert ep["error_rate_episode"] == pytest.approx(ep["errors"] / ep["units_attempted"])
    assert ep["energy_Wh_per_unit"] == pytest.approx(ep["energy_wh"] / ep["units_completed"])
    assert ep["ep_episode"] == pytest.approx(ep["units_completed"] / (ep["energy_wh"] / 1000))
    wage = params.price_per_unit * ep["mpl_episode"] * (1 - params.damage_cost / params.price_per_unit
                                                        * ep["error_rate_episode"])
    assert ep["wage_parity"] == pytest.approx(wage / params.wage_human)
    assert ep["profit"] == pytest.approx(params.price_per_unit * ep["units_completed"]
                                         - params.damage_cost * ep["errors"])


def test_risk_score_is_one_after_any_failure_and_a_budget_share_otherwise():
    env = DishwashingEnv(EconParams.preset("toy"), objective=EconomicObjectiveSpec(mpl_weight=0.0, risk_weight=1.0))
    seen = set()
    for seed in range(40):
        _, rewards, ep = random_episode(env, seed)
        reason = ep["termination_reason"]
        seen.add(reason)
        expected = 1.0 if reason != "max_steps" else ep["catastrophic_steps"] / 3
        assert ep["risk_score"] == pytest.approx(expected)
        assert sum(rewards) == pytest.approx(-expected)
    assert {"sla_violation", "catastrophic_error"} <= seen
