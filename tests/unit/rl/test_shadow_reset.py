"""A reset in the middle of a dishwashing episode restarts the constraint shaping's running
state (the shadow wrapper resets the shaper; the shaper itself reads no step counter), so
the next episode's step penalties still sum to 10 * that episode's violations."""

from __future__ import annotations

import numpy as np
import pytest

from econmotor.config.econ_params import EconParams
from econmotor.config.objective_profile import ObjectiveVector
from econmotor.envs.dishwashing import DishwashingEnv
from econmotor.networks.econ_objective_net import identity_reward_weights
from econmotor.rl.constraint_shaping import ConstraintShaper
from econmotor.rl.shadow import ShadowRewardWrapper
from econmotor.tasks import get_task
from econmotor.valuation import ConstraintSet


def test_mid_episode_reset_does_not_carry_the_running_violation_over():
    params = EconParams.preset("toy").with_overrides({"max_error_rate_sla": 10.0, "max_catastrophic_errors": 1000})
    base = DishwashingEnv(params, reward_mode="legacy", max_steps=80)
    shaper = ConstraintShaper(ConstraintSet(max_error_rate=0.02), "penalty")
    env = ShadowRewardWrapper(base, economics=get_task("dishwashing").economics,
                              weights_for=identity_reward_weights, objective=ObjectiveVector.from_preset("throughput"),
                              constraints=shaper)
    env.reset(seed=1)
    carried = 0.0
    for _ in range(25):  # a fast, careless partial episode above the cap, then an early reset
        _, _, terminated, truncated, info = env.step(np.array([0.9, 0.1], dtype=np.float32))
        assert not (terminated or truncated)
        carried += info["shadow"]["legacy"] - info["shadow"]["learner"]
    assert carried > 0.1  # the abandoned episode had built up a running violation

    env.reset(seed=2)
    penalties, done = [], False
    while not done:  # a full episode, carefuller but still above the cap
        _, _, terminated, truncated, info = env.step(np.array([0.6, 0.5], dtype=np.float32))
        penalties.append(info["shadow"]["legacy"] - info["shadow"]["learner"])
        done = terminated or truncated
    violation = info["shadow_episode"]["constraints"]["violations"]["max_error_rate"]
    assert violation > 0
    assert sum(penalties) == pytest.approx(10.0 * violation, rel=1e-6, abs=1e-9)
