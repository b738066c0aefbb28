"""MuJoCo tasks get a per-step summary whose sums are the metered episode, so shadow mode runs."""

from __future__ import annotations

import numpy as np
import pytest

from econmotor.config.objective_profile import ObjectiveVector
from econmotor.networks.econ_objective_net import identity_reward_weights
from econmotor.rl.shadow import ShadowRewardWrapper
from econmotor.rl.task_env import make_task_env


def test_step_summaries_add_up_to_the_metered_episode():
    task = make_task_env("hopper_courier")
    env = task.env
    env.reset(seed=3)
    env.action_space.seed(3)
    sums = {"units": 0.0, "errors": 0.0, "Wh": 0.0, "d_mpl": 0.0}
    for _ in range(task.max_episode_steps):
        _, _, terminated, truncated, info = env.step(env.action_space.sample())
        for key in sums:
            sums[key] += info["step_summary"][key]
        if terminated or truncated:
            break
    raw = info["econ_episode"]
    assert sums["units"] == pytest.approx(raw["units_completed"], abs=1e-12)
    assert sums["errors"] == raw["errors"]
    assert sums["Wh"] == pytest.approx(raw["energy_wh"], rel=1e-9)
    hours = raw["episode_length_s"] / 3600.0
    assert sums["d_mpl"] == pytest.approx(raw["units_completed"] / hours, rel=1e-9, abs=1e-9)
    assert info["step_summary"]["catastrophic"] == (raw["termination_reason"] == "fall")


def test_shadow_wrapper_runs_on_a_mujoco_task_with_priced_energy():
    task = make_task_env("hopper_courier")
    env = ShadowRewardWrapper(task.env, economics=task.economics, reward_params=task.reward_params,
                              weights_for=identity_reward_weights, objective=ObjectiveVector.from_preset("balanced"))
    env.reset(seed=0)
    env.action_space.seed(0)
    for _ in range(task.max_episode_steps):
        _, reward, terminated, truncated, info = env.step(env.action_space.sample())
        s = info["step_summary"]
        # r_energy is priced in USD for catalog economics: -(pi_e * Wh / 1000)
        expected = (s["mpl_t"] - s["error_rate_t"] - task.economics.energy_price_usd_per_kwh * s["Wh"] / 1000.0
                    - (1.0 if s["catastrophic"] else 0.0) + 0.0) / 4.0
        assert info["shadow"]["objective"] == pytest.approx(expected, rel=1e-9, abs=1e-12)
        assert reward == info["shadow"]["legacy"]
        if terminated or truncated:
            break
    record = info["shadow_episode"]
    assert record["econ"]["termination_reason"] in ("fall", "max_steps")
    assert np.isfinite(record["episode_J"])
