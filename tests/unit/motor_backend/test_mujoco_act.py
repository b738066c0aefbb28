"""The evaluator's action function is SB3's ``predict(normalised obs, deterministic=True)`` exactly, for one
observation and for a batch, for PPO (clipped actions) and SAC (squashed), without predict's per-call cost."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
import torch
from stable_baselines3 import PPO, SAC

from econmotor.motor_backend.mujoco.evaluation import torch_act_fn


@pytest.mark.parametrize("cls", [PPO, SAC])
def test_act_is_predict_on_the_normalised_observation(cls) -> None:
    env = gym.make("Hopper-v5")
    model = cls("MlpPolicy", env, device="cpu", seed=1)
    if hasattr(model.policy, "action_net"):  # PPO: means beyond the bounds, so the clip decides
        torch.nn.init.constant_(model.policy.action_net.bias, 3.0)
    rng = np.random.default_rng(0)
    normalizer = (rng.normal(size=11), rng.random(11) + 0.5, 1e-8, 2.0)
    act = torch_act_fn(model, normalizer)
    obs = rng.normal(size=(6, 11)) * 3.0  # some clipped by the normaliser's clip
    x = np.clip((obs - normalizer[0]) / np.sqrt(normalizer[1] + normalizer[2]), -2.0, 2.0).astype(np.float32)
    np.testing.assert_array_equal(act(obs), model.predict(x, deterministic=True)[0])
    np.testing.assert_array_equal(act(obs[0]), model.predict(x[0], deterministic=True)[0])
    assert np.all(act(obs * 100.0) <= env.action_space.high) and np.all(act(obs * 100.0) >= env.action_space.low)
    env.close()
