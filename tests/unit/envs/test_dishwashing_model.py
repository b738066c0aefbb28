"""Statistical and behavioural tests of the analytic dishwashing workcell model."""

from __future__ import annotations

import math
from dataclasses import replace

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

from econmotor.config.econ_params import EconParams
from econmotor.envs import DISHWASHING_ENV_ID, DishwashingEnv
from econmotor.errors import ConfigError

#: toy params with every termination except max_steps switched off
ENDLESS = replace(EconParams.preset("toy"), max_catastrophic_errors=10**9, max_error_rate_sla=1e9,
                  zero_throughput_patience=10**9)


def run_constant(env: DishwashingEnv, action, seed: int) -> tuple[list[dict], dict]:
    env.reset(seed=seed)
    steps, done = [], False
    while not done:
        _, _, term, trunc, info = env.step(np.asarray(action, dtype=np.float32))
        steps.append(info["step_summary"])
        done = term or trunc
    return steps, info["episode_summary"]


@pytest.mark.parametrize("speed,care", [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.5, 0.3)])
def test_mean_attempts_and_error_rate_match_formulas(speed, care):
    p = ENDLESS
    n = 4000
    steps, ep = run_constant(DishwashingEnv(p, max_steps=n), (speed, care), seed=11)
    assert len(steps) == n and ep["termination_reason"] == "max_steps"
    # formulas written out independently of the env module
    lam = max(0.1, p.base_rate * (0.5 + 0.5 * speed)) * (1 - p.care_cost * care) * p.time_step_s / 60
    mean_attempts = lam + math.exp(-lam)  # E[max(1, Poisson(lam))]
    p_err = min(0.5, max(0.0, p.p_min + p.k_err * speed**p.q_speed * (1 - care) ** p.q_care))
    attempts = np.array([s["attempts"] for s in steps])
    assert abs(attempts.mean() - mean_attempts) < 4 * math.sqrt(lam / n) + 1e-3
    total = attempts.sum()
    err = sum(s["errors"] for s in steps) / total
    assert abs(err - p_err) < 4 * math.sqrt(p_err * (1 - p_err) / total)
    assert ep["energy_wh"] == pytest.approx(total * p.energy_Wh_per_attempt)
    assert ep["units_completed"] == total - sum(s["errors"] for s in steps)


def test_care_lowers_errors_and_speed_raises_attempts():
    p = ENDLESS
    fast, _ = run_constant(DishwashingEnv(p, max_steps=1500), (1.0, 0.0), seed=3)
    slow, _ = run_constant(DishwashingEnv(p, max_steps=1500), (0.0, 0.0), seed=3)
    careful, _ = run_constant(DishwashingEnv(p, max_steps=1500), (1.0, 1.0), seed=3)
    rate = lambda steps: sum(s["errors"] for s in steps) / sum(s["attempts"] for s in steps)
    assert np.mean([s["attempts"] for s in fast]) > np.mean([s["attempts"] for s in slow]) + 0.5
    assert rate(careful) < rate(fast) / 2


def test_catastrophic_error_is_reachable_and_checked_first():
    p = replace(EconParams.preset("toy"), p_min=0.5, zero_throughput_patience=3, max_catastrophic_errors=3)
    reasons = {run_constant(DishwashingEnv(p), (0.0, 1.0), seed)[1]["termination_reason"] for seed in range(20)}
    assert "catastrophic_error" in reasons
    # three all-failed steps with nothing completed satisfy both rules: catastrophe wins
    for seed in range(200):
        steps, ep = run_constant(DishwashingEnv(p), (0.0, 1.0), seed)
        if len(steps) == 3 and all(s["catastrophic"] for s in steps):
            assert ep["termination_reason"] == "catastrophic_error"
            break
    else:
        pytest.fail("no seed gave three catastrophic steps in a row")


def test_sla_violation_is_reachable():
    steps, ep = run_constant(DishwashingEnv(replace(ENDLESS, max_error_rate_sla=0.12)), (1.0, 0.0), seed=0)
    assert ep["termination_reason"] == "sla_violation"
    assert len(steps) >= ENDLESS.min_steps_for_sla
    assert ep["errors"] / ep["units_completed"] > 0.12


def test_zero_throughput_is_reachable():
    p = replace(ENDLESS, p_min=0.5, zero_throughput_patience=2)
    for seed in range(100):
        steps, ep = run_constant(DishwashingEnv(p), (0.0, 1.0), seed)
        if ep["termination_reason"] == "zero_throughput":
            assert len(steps) == 2 and ep["units_completed"] == 0
            return
    pytest.fail("zero_throughput never reached in 100 seeds")


def test_max_steps_is_a_truncation():
    env = DishwashingEnv(EconParams.preset("toy"), max_steps=7)
    env.reset(seed=0)
    for _ in range(7):
        _, _, term, trunc, info = env.step(np.array([0.6, 1.0], dtype=np.float32))
        if term:
            pytest.skip("terminated early with this seed")
    assert trunc and not term and info["episode_summary"]["termination_reason"] == "max_steps"


def test_same_seed_same_episode_and_different_seed_differs():
    a, b = DishwashingEnv(), DishwashingEnv()
    rng = np.random.default_rng(0)
    actions = rng.uniform(0, 1, size=(240, 2)).astype(np.float32)

    def roll(env, seed):
        obs, _ = env.reset(seed=seed)
        out = [obs]
        for act in actions:
            obs, r, term, trunc, info = env.step(act)
            out.append((obs, r, info["step_summary"]["units"], info["step_summary"]["errors"]))
            if term or trunc:
                break
        return out

    first, second = roll(a, 5), roll(b, 5)
    assert len(first) == len(second)
    for x, y in zip(first[1:], second[1:], strict=True):
        assert np.array_equal(x[0], y[0]) and x[1:] == y[1:]
    assert [x[2:] for x in roll(a, 6)[1:]] != [x[2:] for x in first[1:]]


def test_registered_with_gymnasium_and_passes_env_checker():
    env = gym.make(DISHWASHING_ENV_ID, econ_params=EconParams.preset("realistic"))
    assert isinstance(env.unwrapped, DishwashingEnv)
    assert env.unwrapped.params.price_per_unit == EconParams.preset("realistic").price_per_unit
    check_env(DishwashingEnv(), skip_render_check=True)
    obs, _ = env.reset(seed=0)
    assert env.observation_space.contains(obs)


def test_bad_constructor_arguments_are_config_errors():
    with pytest.raises(ConfigError, match="reward_mode"):
        DishwashingEnv(reward_mode="bogus")
    with pytest.raises(ConfigError, match="objective_vector"):
        DishwashingEnv(reward_mode="reward_builder", objective_vector=[1, 2])
    with pytest.raises(ConfigError, match="term_references"):
        DishwashingEnv(term_references={"mpl_per_hour": 0.0})
