"""LagrangeRelabelReplayBuffer: replayed lagrangian rewards carry the *current* multipliers."""

from __future__ import annotations

import numpy as np
import pytest
from gymnasium import spaces
from stable_baselines3 import SAC
from stable_baselines3.common.buffers import ReplayBuffer
from stable_baselines3.common.vec_env import DummyVecEnv

from econmotor.errors import ConfigError
from econmotor.rl.lagrange import LagrangeMultipliers
from econmotor.rl.relabel_buffer import RELABEL_INFO_KEY, LagrangeRelabelReplayBuffer
from econmotor.rl.shadow_log import ShadowRecorder
from econmotor.rl.train_sac_objective import ShadowConfig, build_env, train_sac_objective
from econmotor.valuation import ConstraintSet

NAMES = ("max_error_rate", "max_energy_Wh")
OBS = spaces.Box(-1e6, 1e6, shape=(2,), dtype=np.float32)
ACT = spaces.Box(0.0, 1.0, shape=(2,), dtype=np.float32)
TINY_SAC = {"learning_starts": 30, "batch_size": 16, "train_freq": 1, "gamma": 0.99, "ent_coef": "auto_0.01",
            "policy_kwargs": {"net_arch": [16, 16]}, "device": "cpu", "seed": 0, "verbose": 0}


def make_buffer(n_envs=1, size=64, lambdas=(0.0, 0.0)):
    mult = LagrangeMultipliers(NAMES, lr=0.0)
    mult.values.update(zip(NAMES, lambdas, strict=True))
    return LagrangeRelabelReplayBuffer(size, OBS, ACT, device="cpu", n_envs=n_envs, multipliers=mult), mult


def info(unshaped, costs):
    return {RELABEL_INFO_KEY: {"reward_unshaped": unshaped, "cost_increments": dict(zip(NAMES, costs, strict=True))}}


def fill(buf, n_steps):
    """Transition (k, env e): obs = (k, e), unshaped reward 0.1*k + e, costs (0.01*k, -0.5*e + 0.2)."""
    expected = {}
    for k in range(n_steps):
        obs = np.array([[k, e] for e in range(buf.n_envs)], dtype=np.float32)
        infos = [info(0.1 * k + e, (0.01 * k, -0.5 * e + 0.2)) for e in range(buf.n_envs)]
        shaped = np.array([-99.0] * buf.n_envs, dtype=np.float32)  # what the env returned: must not be used
        buf.add(obs, obs + 1, np.zeros((buf.n_envs, 2), np.float32), shaped, np.zeros(buf.n_envs), infos)
        for e in range(buf.n_envs):
            expected[(k, e)] = (0.1 * k + e, np.array([0.01 * k, -0.5 * e + 0.2]))
    return expected


def test_the_buffer_stores_the_unshaped_reward_and_the_cost_increments_from_infos():
    buf, _ = make_buffer(n_envs=2)
    fill(buf, 3)
    np.testing.assert_allclose(buf.rewards_unshaped[:3], [[0.0, 1.0], [0.1, 1.1], [0.2, 1.2]])
    np.testing.assert_allclose(buf.cost_increments[2], [[0.02, 0.2], [0.02, -0.3]])
    np.testing.assert_allclose(buf.rewards[:3], -99.0)  # the env-returned (collection-time) reward, kept


@pytest.mark.parametrize("n_envs", [1, 2])
def test_a_sample_after_the_multipliers_moved_uses_the_new_multipliers(n_envs):
    buf, mult = make_buffer(n_envs=n_envs, lambdas=(0.5, 0.0))
    expected = fill(buf, 10)
    mult.values.update({"max_error_rate": 3.0, "max_energy_Wh": 2.0})  # after collection
    batch = buf.sample(200)
    assert batch.rewards.dtype == batch.observations.dtype  # float32, as SB3's critic expects
    obs, rewards = batch.observations.numpy(), batch.rewards.numpy()[:, 0]
    assert {int(e) for e in obs[:, 1]} == set(range(n_envs))
    for (k, e), r in zip(obs.astype(int), rewards, strict=True):
        unshaped, costs = expected[(k, e)]
        hand = unshaped - (3.0 * costs[0] + 2.0 * costs[1])
        assert r == pytest.approx(hand, abs=1e-6)
    # (k=4, e=0): 0.4 - (3 * 0.04 + 2 * 0.2) = -0.12
    assert buf.relabelled_rewards(np.array([4]), np.array([0]))[0] == pytest.approx(-0.12, abs=1e-7)


def test_with_all_multipliers_zero_the_sample_is_the_unshaped_reward():
    buf, _ = make_buffer(n_envs=2)
    expected = fill(buf, 10)
    batch = buf.sample(100)
    for (k, e), r in zip(batch.observations.numpy().astype(int), batch.rewards.numpy()[:, 0], strict=True):
        assert r == pytest.approx(expected[(k, e)][0], abs=1e-6)


def test_missing_relabel_info_and_the_memory_optimised_layout_are_refused():
    buf, mult = make_buffer()
    obs = np.zeros((1, 2), np.float32)
    with pytest.raises(ConfigError, match="lagrange_relabel"):
        buf.add(obs, obs, obs, np.zeros(1), np.zeros(1), [{}])
    with pytest.raises(ValueError, match="optimize_memory_usage"):
        LagrangeRelabelReplayBuffer(64, OBS, ACT, optimize_memory_usage=True, handle_timeout_termination=False,
                                    multipliers=mult)
    with pytest.raises(ValueError, match="no multiplier"):
        LagrangeRelabelReplayBuffer(64, OBS, ACT, multipliers=mult, names=("min_wage_parity",))


def shadow_config(**kw):
    base = {"env": "dishwashing", "total_steps": 80, "max_episode_steps": 20, "eval_episodes": 0,
            "net_arch": (16, 16), "batch_size": 16, "learning_starts": 30, "use_objective_reward": True,
            "reward_weights": "analytic", "constraints": ConstraintSet(max_error_rate=0.02, max_energy_Wh=5.0),
            "constraint_mode": "lagrangian", "lagrange_lr": 2.0}
    return ShadowConfig(**{**base, **kw})


def test_real_sac_stores_what_the_shadow_wrapper_shaped_and_telescopes_per_episode():
    # constant multipliers (lr 0): the relabelled reward is the reward the env returned
    config = shadow_config(lagrange_lr=0.0, lagrange_init=0.7)
    recorder = ShadowRecorder()
    env, _, shaper = build_env(config, recorder)
    model = SAC("MlpPolicy", env, replay_buffer_class=LagrangeRelabelReplayBuffer,
                replay_buffer_kwargs={"multipliers": shaper.multipliers}, **TINY_SAC)
    model.learn(80)
    buf = model.replay_buffer
    n = buf.pos
    assert n == 80 and buf.names == tuple(ConstraintSet(max_error_rate=0.02, max_energy_Wh=5.0).active())
    zeros = np.zeros(n, dtype=int)
    np.testing.assert_allclose(buf.relabelled_rewards(np.arange(n), zeros), buf.rewards[:n, 0], atol=1e-6)
    # each episode's cost increments sum to its signed costs (the shaping telescopes)
    ends = np.flatnonzero(buf.dones[:n, 0]) + 1
    assert len(ends) == len(recorder.records) >= 2
    for start, end, record in zip([0, *ends[:-1]], ends, recorder.records, strict=True):
        assert end - start == record["steps"]
        total = buf.cost_increments[start:end, 0].sum(axis=0)
        np.testing.assert_allclose(total, [record["constraints"]["signed_costs"][k] for k in buf.names], atol=1e-9)
    # multipliers at 0: the learner's unshaped (objective) reward
    shaper.multipliers.values.update(dict.fromkeys(buf.names, 0.0))
    np.testing.assert_allclose(buf.relabelled_rewards(np.arange(20), zeros[:20]),
                               buf.rewards_unshaped[:20, 0], atol=1e-6)


def test_real_sac_with_two_envs_relabels_both_columns():
    config = shadow_config()
    envs = [build_env(config, ShadowRecorder()) for _ in range(2)]
    shared = envs[0][2].multipliers
    for _, _, shaper in envs[1:]:
        shaper.multipliers = shared  # one dual variable for both workers
    vec = DummyVecEnv([lambda e=e: e[0] for e in envs])
    model = SAC("MlpPolicy", vec, replay_buffer_class=LagrangeRelabelReplayBuffer,
                replay_buffer_kwargs={"multipliers": shared}, **TINY_SAC)
    model.learn(120)
    buf = model.replay_buffer
    assert buf.n_envs == 2 and buf.pos == 60
    assert np.all(np.abs(buf.cost_increments[:60]).sum(axis=(0, 2)) > 0)  # both env columns filled
    assert shared.history  # multipliers moved during training (6 episodes)
    assert model._n_updates > 0  # SAC trained on relabelled samples
    inds = np.arange(60)
    for e in (0, 1):
        hand = buf.rewards_unshaped[inds, e] - buf.cost_increments[inds, e] @ np.array(
            [shared.values[k] for k in buf.names])
        np.testing.assert_allclose(buf.relabelled_rewards(inds, np.full(60, e)), hand, atol=1e-6)


@pytest.mark.parametrize(("mode", "relabel", "cls"), [("lagrangian", True, LagrangeRelabelReplayBuffer),
                                                      ("lagrangian", False, ReplayBuffer),
                                                      ("penalty", True, ReplayBuffer)])
def test_train_sac_objective_uses_the_relabel_buffer_in_lagrangian_mode(mode, relabel, cls):
    result = train_sac_objective(shadow_config(constraint_mode=mode, lagrange_relabel=relabel))
    buf = result.model.replay_buffer
    assert type(buf) is cls
    if cls is LagrangeRelabelReplayBuffer:
        assert result.multipliers  # updated at episode ends
        assert buf.lambdas().tolist() == [result.multipliers[-1][k] for k in buf.names]
