"""The couriers' robot records hold Gymnasium v5's own parameters and fall rules."""

from __future__ import annotations

import inspect
import os

import gymnasium as gym
import numpy as np
import pytest

from econmotor.errors import ConfigError
from econmotor.robots.gym_couriers import ROBOTS, UNSUPPORTED_KWARGS, is_healthy, robot_spec


def gymnasium_defaults(env_id: str) -> dict:
    cls = gym.envs.registration.load_env_creator(gym.spec(env_id).entry_point)
    return {name: p.default for name, p in inspect.signature(cls.__init__).parameters.items()
            if p.default is not inspect.Parameter.empty and name != "default_camera_config"}


@pytest.mark.parametrize("env_id", list(ROBOTS))
def test_each_record_holds_the_installed_gymnasium_defaults(env_id):
    robot = ROBOTS[env_id]
    assert dict(robot.defaults) == gymnasium_defaults(env_id)
    assert robot.max_episode_steps == gym.spec(env_id).max_episode_steps
    spec = robot_spec(env_id)
    assert os.path.isfile(spec.xml_path)
    assert spec.xml_path == gym.make(env_id).unwrapped.fullpath


@pytest.mark.parametrize("env_id", list(ROBOTS))
def test_the_fall_rule_is_gymnasiums_healthy_check(env_id):
    """is_healthy (the mjx fall) agrees with the Gymnasium env's own is_healthy on random states."""
    env = gym.make(env_id).unwrapped
    spec = robot_spec(env_id)
    rule = spec.robot.healthy_rule(spec.params)
    rng = np.random.default_rng(0)
    env.reset(seed=0)
    agree = {True: 0, False: 0}
    for _ in range(300):
        qpos = env.init_qpos + rng.normal(0, 0.4, env.model.nq)
        qvel = rng.normal(0, 60, env.model.nv)
        qpos[rule.z_index] = rng.uniform(rule.z_range[0] - 0.5, min(rule.z_range[1], 3.0) + 0.5)
        env.set_state(qpos, qvel)
        expected = bool(env.is_healthy)
        assert bool(is_healthy(rule, qpos, qvel, np)) == expected
        agree[expected] += 1
    assert min(agree.values()) > 20  # both outcomes were exercised


def test_env_kwargs_override_defaults_and_unknown_ones_are_config_errors():
    spec = robot_spec("Hopper-v5", {"healthy_z_range": (0.5, 2.0), "max_episode_steps": 300})
    assert spec.params["healthy_z_range"] == (0.5, 2.0) and spec.max_episode_steps == 300
    assert spec.robot.healthy_rule(spec.params).z_range == (0.5, 2.0)
    with pytest.raises(ConfigError, match=r"env_kwargs\.main_body"):
        robot_spec("Ant-v5", {"main_body": 2}, "my.yaml")
    with pytest.raises(ConfigError, match=r"env_kwargs\.bogus"):
        robot_spec("Ant-v5", {"bogus": 1})
    with pytest.raises(ConfigError, match="Cheetah"):
        robot_spec("HalfCheetah-v5")
    assert "terminate_when_unhealthy" in UNSUPPORTED_KWARGS
