"""The shared loop's SB3 learner learns in chunks (``model.learn(n, reset_num_timesteps=False)``) what one
``model.learn`` learns: same weights, same step count, same episode buffer."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
from stable_baselines3 import PPO
from stable_baselines3.common.monitor import Monitor
from stable_baselines3.common.vec_env import DummyVecEnv

from econmotor.motor_backend.sb3_learner import SB3Learner


def _model() -> PPO:
    venv = DummyVecEnv([lambda: Monitor(gym.make("Pendulum-v1")) for _ in range(2)])
    venv.seed(3)
    return PPO("MlpPolicy", venv, n_steps=64, batch_size=32, n_epochs=2, seed=3, device="cpu")


def _weights(model: PPO) -> np.ndarray:
    return np.concatenate([p.detach().numpy().ravel() for p in model.policy.parameters()])


def test_chunks_learn_what_one_learn_call_learns() -> None:
    whole = _model()
    whole.learn(4 * 128)
    learner = SB3Learner(_model())
    assert learner.chunk_steps == 128  # one rollout: n_steps x envs
    for _ in range(4):  # four chunks of one rollout each
        learner.learn(learner.env_steps + learner.chunk_steps)
    assert learner.env_steps == whole.num_timesteps == 512
    np.testing.assert_array_equal(_weights(learner.model), _weights(whole))
    returns = [ep["r"] for ep in whole.ep_info_buffer]
    assert returns and [ep["r"] for ep in learner.model.ep_info_buffer] == returns
    learner.close()
