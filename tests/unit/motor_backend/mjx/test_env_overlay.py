"""The batched GymCourierEnv on the hopper courier: overlay invariant, auto-reset, raw-metric keys, one compile."""

from __future__ import annotations

import gymnasium as gym
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from econmotor.economics.courier_formulas import episode_metric
from econmotor.motor_backend.mujoco.backend import MujocoBackend
from econmotor.motor_backend.mujoco.env_factory import make_env
from econmotor.motor_backend.mujoco.evaluation import flatten_episode

from .conftest import NUM_ENVS, every_term_objective


@pytest.fixture(scope="module")
def rollout(hopper):
    """Random actions until both envs finished at least two episodes: per-step states on the host."""
    env = hopper.env
    state = hopper.reset(jax.random.PRNGKey(0), NUM_ENVS)
    rng = np.random.default_rng(0)
    steps = []
    for _ in range(600):
        action = rng.uniform(env.action_low, env.action_high, (NUM_ENVS, env.action_size)).astype(np.float32)
        prev = state
        state = hopper.step(state, jnp.asarray(action))
        steps.append((jax.device_get(prev), jax.device_get(state)))
        if sum(float(np.sum(s.done)) for _, s in steps) >= 2 * NUM_ENVS + 2:
            break
    return env, steps


def test_layout_matches_the_gymnasium_env(hopper):
    env, gym_env = hopper.env, gym.make("Hopper-v5")
    assert env.observation_size == gym_env.observation_space.shape[0] == 11
    np.testing.assert_array_equal(env.action_low, gym_env.action_space.low)
    np.testing.assert_array_equal(env.action_high, gym_env.action_space.high)
    assert env.control_dt_s == pytest.approx(gym_env.unwrapped.dt)
    assert env.max_episode_steps == gym_env.spec.max_episode_steps
    state = hopper.reset(jax.random.PRNGKey(1), NUM_ENVS)
    qpos, qvel = np.asarray(state.data.qpos), np.asarray(state.data.qvel)
    noise = gym_env.unwrapped._reset_noise_scale
    assert np.all(np.abs(qpos - gym_env.unwrapped.init_qpos) <= noise + 1e-7)
    assert not np.allclose(qpos[0], qpos[1])  # each env draws its own noise
    np.testing.assert_allclose(np.asarray(state.obs), np.concatenate([qpos[:, 1:], np.clip(qvel, -10, 10)], 1))
    assert set(state.finished) == set(env.metric_keys)


def test_each_overlay_term_sums_to_its_episode_metric(rollout):
    env, steps = rollout
    sums = np.zeros(NUM_ENVS)
    checked = 0
    for _, state in steps:
        sums += state.reward
        for i in np.flatnonzero(state.done):
            row = env.finished_to_dicts({k: v[i: i + 1] for k, v in state.finished.items()})[0]
            assert set(env.scales) == {"mpl_per_hour", "energy_kwh", "error_rate", "novelty_score", "risk_score"}
            weighted = 0.0
            for key in env.scales:
                assert row[f"overlay_{key}_raw"] == pytest.approx(episode_metric(row, key), rel=2e-5, abs=1e-9), key
                assert row[f"overlay_{key}_weighted"] == pytest.approx(env.factors[key] * row[f"overlay_{key}_raw"])
                weighted += row[f"overlay_{key}_weighted"]
            assert row["overlay_return"] == pytest.approx(weighted, rel=1e-4, abs=1e-3)
            # the episode's rewards = its task return + the overlay's J(T)
            assert sums[i] == pytest.approx(row["return"] + row["overlay_return"], rel=1e-4, abs=1e-3)
            assert row["units_attempted"] == pytest.approx(row["units_completed"] + row["errors"])
            sums[i] = 0.0
            checked += 1
    assert checked >= 2 * NUM_ENVS


def test_finished_rows_have_the_mujoco_backends_keys_and_types(rollout):
    env, steps = rollout
    _, state = next((p, s) for p, s in steps if s.done.any())
    i = int(np.flatnonzero(state.done)[0])
    row = env.finished_to_dicts({k: v[i: i + 1] for k, v in state.finished.items()})[0]
    recipe, _ = MujocoBackend().recipe("hopper_courier", every_term_objective())
    cpu_env = make_env(recipe, seed=0)
    cpu_env.reset(seed=0)
    while True:
        _, _, terminated, truncated, info = cpu_env.step(np.zeros(3))
        if terminated or truncated:
            break
    cpu_row = flatten_episode(info)
    assert set(row) == set(cpu_row)
    assert {k: type(v) for k, v in row.items()} == {k: type(v) for k, v in cpu_row.items()}
    assert row["termination_reason"] == ("fall" if state.finished["fell"][i] else "max_steps")


def test_auto_reset_starts_the_next_episode_in_the_same_step(rollout):
    _, steps = rollout
    seen = 0
    for prev, state in steps:
        for i in np.flatnonzero(state.done):
            assert state.finished["length_steps"][i] == prev.episode["steps"][i] + 1
            assert state.finished["fell"][i] == 1.0 and state.truncated[i] == 0.0
            assert state.episode["steps"][i] == 0 and state.episode["units"][i] == 0
            assert state.episode["overlay_j"][i] == 0
            x = state.data.qpos[i, 0]
            assert state.episode["best_x"][i] == state.episode["x0"][i] == x
            np.testing.assert_allclose(state.obs[i], np.concatenate([state.data.qpos[i, 1:],
                                                                      np.clip(state.data.qvel[i], -10, 10)]))
            assert abs(x) <= 5e-3 + 1e-7  # a fresh reset state, not the fallen one
            seen += 1
        for i in np.flatnonzero(state.done == 0):
            assert state.episode["steps"][i] == prev.episode["steps"][i] + 1
    assert seen >= 2
    # novelty visit counts outlive episodes: one count per step taken
    assert int(steps[-1][1].lifelong["novelty_counts"].sum()) == len(steps) * NUM_ENVS


def test_time_limit_truncates_and_resets(hopper):
    env = hopper.env
    state = hopper.reset(jax.random.PRNGKey(2), NUM_ENVS)
    episode = dict(state.episode)
    episode["control_steps"] = jnp.asarray([env.max_episode_steps - 1, 5], jnp.float32)
    state = hopper.step(state._replace(episode=episode), jnp.zeros((NUM_ENVS, env.action_size)))
    np.testing.assert_array_equal(np.asarray(state.done), [1.0, 0.0])
    np.testing.assert_array_equal(np.asarray(state.truncated), [1.0, 0.0])
    row = env.finished_to_dicts({k: np.asarray(v)[:1] for k, v in state.finished.items()})[0]
    assert row["termination_reason"] == "max_steps" and row["errors"] == 0.0
    assert row["length_steps"] == env.max_episode_steps
    assert float(state.episode["control_steps"][0]) == 0.0 and float(state.episode["control_steps"][1]) == 6.0


def test_step_compiles_once(hopper, rollout):
    assert hopper.step._cache_size() == 1  # every step of every test reused one program
