"""The mjx PPO's KL-adapted learning rate (mjx/ppo.py): rsl_rl's rule on the optimizer's state."""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np
import pytest

from econmotor.motor_backend.mjx import ppo


def test_gaussian_kl_is_the_closed_form() -> None:
    m0, m1 = jnp.zeros((2, 3)), jnp.full((2, 3), 0.1)
    s = jnp.log(jnp.full(3, 0.2))
    assert float(ppo.gaussian_kl(m0, m1, s, s)) == pytest.approx(3 * 0.1**2 / (2 * 0.04), rel=1e-5)
    assert float(ppo.gaussian_kl(m0, m0, s, s)) == pytest.approx(0.0, abs=1e-7)


def test_the_rate_follows_the_kl_within_its_bounds() -> None:
    cfg = ppo.PPOConfig.from_mapping({"desired_kl": 0.01, "learning_rate": 1e-4, "lr_bounds": [1e-5, 2e-4]})
    opt = ppo.make_optimizer(cfg)
    state = opt.init({"w": jnp.zeros(3)})
    rate = lambda st: float(st[1].hyperparams["learning_rate"])
    assert rate(state) == pytest.approx(1e-4)
    high = ppo.adapt_learning_rate(state, jnp.asarray(0.05), cfg)  # > 2 x desired: / 1.5
    assert rate(high) == pytest.approx(1e-4 / 1.5, rel=1e-6)
    low = ppo.adapt_learning_rate(state, jnp.asarray(0.001), cfg)  # < desired / 2: x 1.5, capped at 2e-4
    assert rate(low) == pytest.approx(1.5e-4, rel=1e-6)
    assert rate(ppo.adapt_learning_rate(low, jnp.asarray(0.0), cfg)) == pytest.approx(2e-4, rel=1e-6)
    assert rate(ppo.adapt_learning_rate(state, jnp.asarray(0.01), cfg)) == pytest.approx(1e-4, rel=1e-6)
    floor = state
    for _ in range(20):
        floor = ppo.adapt_learning_rate(floor, jnp.asarray(1.0), cfg)
    assert rate(floor) == pytest.approx(1e-5, rel=1e-6)
    assert np.isfinite(rate(floor))


def test_the_humanoid_recipe_adapts_on_minibatches_of_thousands() -> None:
    from econmotor.motor_backend.mjx.backend import MjxBackend

    backend = MjxBackend()
    cfg = backend.ppo_config(backend.settings("humanoid_locomotion_g1"), None)
    assert cfg.desired_kl == 0.01 and cfg.num_minibatches == 4
    assert 4096 * cfg.unroll_length // cfg.num_minibatches >= 2000  # the catalog's 4,096 envs: 20,480 per minibatch
    with pytest.raises(Exception, match="lr_bounds"):
        ppo.PPOConfig.from_mapping({"lr_bounds": [1e-3, 1e-5]})
