"""PPO in JAX (mjx/ppo.py): GAE, the normaliser, learning on a small pure-JAX env, and no recompilation.

The env here is a real env of the mjx contract (``base_env.State`` fields, auto-reset, ``finished``
metrics), only physically trivial: a point on a line steered towards a target, so PPO's
learning is checked in seconds without MJX's compile time (the MJX env is exercised by the
integration tests)."""

from __future__ import annotations

from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from econmotor.errors import ConfigError
from econmotor.motor_backend.mjx import networks as nets
from econmotor.motor_backend.mjx import ppo


class LineState(NamedTuple):
    data: Any
    obs: jax.Array
    reward: jax.Array
    done: jax.Array
    truncated: jax.Array
    episode: dict
    finished: dict
    key: jax.Array
    t: jax.Array


class LineEnv:
    """Position x in [-2, 2], target g in [-1, 1]; x += 0.1 a; reward -|x - g|; falls past |x| = 2; 20 steps."""

    observation_size, action_size, max_episode_steps, control_dt_s = 2, 1, 20, 0.05
    action_low, action_high = np.array([-1.0], np.float32), np.array([1.0], np.float32)
    metric_keys = ("return", "length_steps")

    def _fresh(self, key):
        x, g = jax.random.uniform(key, (2,), minval=-1.0, maxval=1.0)
        return jnp.stack([x, g])

    def reset(self, key, num_envs):
        keys = jax.random.split(key, num_envs)
        obs = jax.vmap(self._fresh)(keys)
        zeros = jnp.zeros((num_envs,), jnp.float32)
        ep = {"return": zeros, "length_steps": zeros}
        return LineState(None, obs, zeros, zeros, zeros, ep, dict(ep), keys, zeros)

    def step(self, state, action):
        x = state.obs[:, 0] + 0.1 * action[:, 0]
        reward = -jnp.abs(x - state.obs[:, 1])
        t = state.t + 1
        fell = jnp.abs(x) > 2.0
        truncated = (t >= self.max_episode_steps) & ~fell
        done = fell | truncated
        ep = {"return": state.episode["return"] + reward, "length_steps": state.episode["length_steps"] + 1}
        keys = jax.vmap(lambda k: jax.random.split(k)[0])(state.key)
        fresh = jax.vmap(self._fresh)(keys)
        obs = jnp.where(done[:, None], fresh, jnp.stack([x, state.obs[:, 1]], axis=1))
        f = done.astype(jnp.float32)
        return LineState(None, obs, reward, f, truncated.astype(jnp.float32),
                         {k: v * (1 - f) for k, v in ep.items()}, ep, keys, t * (1 - f))


def test_normaliser_matches_numpy_over_batches() -> None:
    rng = np.random.default_rng(0)
    data = [rng.normal(3.0, 2.0, size=(50, 4)).astype(np.float32) for _ in range(5)]
    stats = nets.init_stats(4)
    for batch in data:
        stats = nets.update_stats(stats, jnp.asarray(batch))
    allx = np.concatenate(data)
    np.testing.assert_allclose(stats.mean, allx.mean(0), rtol=1e-4, atol=1e-4)
    np.testing.assert_allclose(stats.var, allx.var(0), rtol=1e-3)
    x = nets.normalize(stats, jnp.asarray(allx), 10.0)
    np.testing.assert_allclose(np.mean(np.asarray(x), 0), 0.0, atol=1e-3)


def test_gae_matches_a_loop_with_falls_and_time_limits() -> None:
    rng = np.random.default_rng(1)
    T, N, gamma, lam = 6, 3, 0.9, 0.8
    reward, value = rng.normal(size=(T, N)), rng.normal(size=(T, N))
    done, trunc = np.zeros((T, N)), np.zeros((T, N))
    done[2, 0] = 1  # a fall
    done[3, 1] = trunc[3, 1] = 1  # a time limit
    last = rng.normal(size=N)
    tr = ppo.Transition(*(jnp.zeros((T, N)),) * 4, jnp.asarray(value), jnp.asarray(reward), jnp.asarray(done),
                        jnp.asarray(trunc))
    adv, target = ppo.gae(tr, jnp.asarray(last), gamma, lam)
    expected = np.zeros((T, N))
    for n in range(N):
        acc = 0.0
        for t in reversed(range(T)):
            nv = last[n] if t == T - 1 else value[t + 1, n]
            if trunc[t, n]:
                acc = 0.0  # masked: neither learns nor carries across the reset
            else:
                term = done[t, n]
                acc = reward[t, n] + gamma * (1 - term) * nv - value[t, n] + gamma * lam * (1 - term) * acc
            expected[t, n] = acc
    np.testing.assert_allclose(adv, expected, rtol=1e-5, atol=1e-5)
    np.testing.assert_allclose(target, expected + value, rtol=1e-5, atol=1e-5)


def test_config_rejects_unknown_and_bad_hyperparameters() -> None:
    with pytest.raises(ConfigError, match="unknown mjx PPO hyperparameter"):
        ppo.PPOConfig.from_mapping({"n_steps": 5}, "tasks.yaml")
    with pytest.raises(ConfigError, match="unroll_length"):
        ppo.PPOConfig.from_mapping({"unroll_length": 0})
    cfg = ppo.PPOConfig.from_mapping({"hidden_sizes": [8, 8], "learning_rate": "1e-3"})
    assert cfg.hidden_sizes == (8, 8) and cfg.learning_rate == 1e-3


def test_ppo_learns_the_line_task_and_compiles_each_function_once() -> None:
    env = LineEnv()
    cfg = ppo.PPOConfig(unroll_length=20, learning_rate=3e-3, hidden_sizes=(32, 32), num_epochs=4)
    state = ppo.init_train_state(env, cfg, 32, seed=0)
    iteration = ppo.make_train_iteration(env, cfg, 32)
    evaluate = ppo.make_evaluate(env, cfg, 16)

    def eval_return(learner, seed):
        first, seen = evaluate(learner.params, learner.stats, jax.random.PRNGKey(seed))
        assert bool(jnp.all(seen))
        return float(jnp.mean(first["return"]))

    before = eval_return(state.learner, 1)
    for _ in range(60):
        state, metrics = iteration(state)
    after = eval_return(state.learner, 2)
    assert metrics["episodes"] > 0 and np.isfinite(float(metrics["value_loss"]))
    assert float(state.learner.stats.count) == pytest.approx(60 * 20 * 32)  # normaliser saw every observation
    assert after > before + 2.0, (before, after)  # -|x - g| summed over 20 steps: steering pays
    assert iteration._cache_size() == 1 and evaluate._cache_size() == 1


def test_critic_warm_up_moves_the_critic_only_and_compiles_once() -> None:
    """``actor_weight`` 0: the actor (and its noise) stays bit for bit while the critic learns; then 1 moves it."""
    env = LineEnv()
    cfg = ppo.PPOConfig(unroll_length=20, learning_rate=3e-3, hidden_sizes=(16, 16), activation="elu",
                        critic_warmup_iterations=4)
    state = ppo.init_train_state(env, cfg, 16, seed=3)
    iteration = ppo.make_train_iteration(env, cfg, 16)
    start = jax.device_get(state.learner.params)
    losses = []
    for _ in range(cfg.critic_warmup_iterations):
        state, metrics = iteration(state, 0.0)
        losses.append(float(metrics["value_loss"]))
    warmed = jax.device_get(state.learner.params)
    for key in ("policy", "log_std"):
        for a, b in zip(jax.tree_util.tree_leaves(start[key]), jax.tree_util.tree_leaves(warmed[key]), strict=True):
            np.testing.assert_array_equal(a, b)
    assert not np.array_equal(start["value"][0]["w"], warmed["value"][0]["w"])
    assert losses[-1] < losses[0]  # the critic learned the policy's values
    state, _ = iteration(state, 1.0)
    assert not np.array_equal(warmed["policy"][0]["w"], np.asarray(state.learner.params["policy"][0]["w"]))
    assert iteration._cache_size() == 1  # one program for both weights
