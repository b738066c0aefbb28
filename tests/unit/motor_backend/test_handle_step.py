"""Every backend's deployed handle answers ``step(obs)`` with exactly what ``act(obs)`` answers; the ONNX
backends (mujoco, mjx, holosoma) deploy one handle class."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from stable_baselines3 import SAC

from econmotor.envs import DishwashingEnv
from econmotor.motor_backend.base import PolicyHandle
from econmotor.motor_backend.dishwashing.backend import SACPolicyHandle
from econmotor.motor_backend.mujoco.export import export_onnx
from econmotor.motor_backend.onnx_policy import OnnxPolicyHandle


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


def test_one_onnx_handle_reads_either_format_and_one_row_as_a_batch(hopper_onnx):
    path, space = hopper_onnx  # econmotor's format: no Holosoma entries, no time_step input
    handle = OnnxPolicyHandle(path)
    assert handle.metadata == {"task_id": "hopper_courier"} and handle.holosoma_metadata == {}
    assert handle.dof_names == [] and handle.kp is None and not handle.takes_time_step
    batch = observations(space)
    assert np.array_equal(handle.step(batch[1], time_step=5), handle.act(batch[1], time_step=5))
    np.testing.assert_allclose(handle.act(batch[:1]), handle.act(batch)[:1], atol=1e-6)  # the one-row fast path
    assert handle.act(batch[:1]).shape == (1, handle.action_dim)
