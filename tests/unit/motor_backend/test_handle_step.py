"""Every backend's deployed handle answers ``step(obs)`` with exactly what ``act(obs)`` answers."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from stable_baselines3 import SAC

from econmotor.envs import DishwashingEnv
from econmotor.motor_backend.base import PolicyHandle
from econmotor.motor_backend.dishwashing.backend import SACPolicyHandle
from econmotor.motor_backend.holosoma.backend import HolosomaPolicyHandle
from econmotor.motor_backend.mujoco.export import OnnxPolicyHandle, export_onnx


def observations(space: gym.spaces.Box, n: int = 4) -> np.ndarray:
    space.seed(0)
    return np.stack([space.sample() for _ in range(n)]).astype(np.float32)


def test_dishwashing_handle_step_is_act():
    env = DishwashingEnv()
    handle = SACPolicyHandle(SAC("MlpPolicy", env, seed=0, device="cpu"), "in-memory")
    assert isinstance(handle, PolicyHandle)
    for obs in observations(env.observation_space):
        assert np.array_equal(handle.step(obs), handle.act(obs))


@pytest.fixture(scope="module")
def hopper_onnx(tmp_path_factory):
    env = gym.make("Hopper-v5")
    model = SAC("MlpPolicy", env, seed=0, device="cpu", policy_kwargs={"net_arch": [16, 16]})
    path = export_onnx(model, None, tmp_path_factory.mktemp("onnx") / "policy.onnx", {"task_id": "hopper_courier"})
    yield path, env.observation_space
    env.close()


def test_mujoco_onnx_handle_step_is_act_for_one_observation_and_a_batch(hopper_onnx):
    path, space = hopper_onnx
    handle = OnnxPolicyHandle(path)
    assert isinstance(handle, PolicyHandle)
    batch = observations(space)
    assert np.array_equal(handle.step(batch), handle.act(batch))
    assert np.array_equal(handle.step(batch[0]), handle.act(batch[0]))
    assert handle.step(batch[0]).shape == (3,)


def test_holosoma_handle_step_is_act(hopper_onnx):
    path, space = hopper_onnx  # any single-input ONNX actor loads; Holosoma metadata is optional
    handle = HolosomaPolicyHandle(path)
    assert isinstance(handle, PolicyHandle)
    batch = observations(space)
    assert np.array_equal(handle.step(batch), handle.act(batch))
    assert np.array_equal(handle.step(batch[1], time_step=5), handle.act(batch[1], time_step=5))
