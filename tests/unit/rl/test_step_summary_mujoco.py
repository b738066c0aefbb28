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


def shadow_episode(vector, seed, energy_term="wh"):
    task = make_task_env("hopper_courier")
    env = ShadowRewardWrapper(task.env, economics=task.economics, weights_for=identity_reward_weights,
                              objective=ObjectiveVector.from_list(vector, energy_term=energy_term))
    env.reset(seed=seed)
    env.action_space.seed(seed)
    steps = []
    for _ in range(task.max_episode_steps):
        _, reward, terminated, truncated, info = env.step(env.action_space.sample())
        steps.append((reward, info))
        if terminated or truncated:
            break
    return task, steps


@pytest.mark.parametrize("energy_term", ["wh", "usd"])
def test_shadow_wrapper_runs_on_a_mujoco_task_with_priced_energy(energy_term):
    task, steps = shadow_episode([1.0, 1.0, 1.0, 1.0, 0.0], seed=0, energy_term=energy_term)
    usd_per_wh = task.economics.energy_price_usd_per_kwh / 1000.0 if energy_term == "usd" else 1.0
    units = errors = novelty = 0.0
    mpl_prev = err_prev = 0.0
    dt_h = task.dt_s / 3600.0
    for t, (reward, info) in enumerate(steps, start=1):
        s = info["step_summary"]
        units, errors, novelty = units + s["units"], errors + s["errors"], novelty + s["novelty"]
        mpl, err = units / (t * dt_h), (errors / (units + errors) if units + errors > 0 else 0.0)
        fell = 1.0 if s["termination_reason"] == "fall" else 0.0
        # increments of the running episode metrics; r_energy is -Wh on this priced task (spec §7), and
        # -(pi_e * Wh / 1000) USD only under the objective option energy_term="usd"
        expected = ((mpl - mpl_prev) - (err - err_prev) - usd_per_wh * s["Wh"] - fell) / 4.0
        assert info["shadow"]["objective"] == pytest.approx(expected, rel=1e-9, abs=1e-12)
        assert s["novelty_running"] == pytest.approx(novelty / t, rel=1e-12)
        assert reward == info["shadow"]["legacy"]
        mpl_prev, err_prev = mpl, err
    record = steps[-1][1]["shadow_episode"]
    assert record["econ"]["termination_reason"] in ("fall", "max_steps")
    assert np.isfinite(record["episode_J"])


def test_step_objective_rewards_sum_to_the_episode_j_on_hopper_courier():
    """The invariant on a real MuJoCo episode, every term weighted (novelty: mean visit bonus)."""
    _, steps = shadow_episode([1.0, 2.0, 0.5, 1.0, 3.0], seed=4)
    record = steps[-1][1]["shadow_episode"]
    assert record["steps"] == len(steps) > 1
    total = sum(info["shadow"]["objective"] for _, info in steps)
    assert total == pytest.approx(record["episode_J"], rel=1e-6, abs=1e-9)
    for name, value in record["episode_terms"].items():
        assert record["term_totals"][name] == pytest.approx(value, rel=1e-6, abs=1e-9), name
    assert record["term_totals"]["r_safety"] == (-1.0 if record["econ"]["termination_reason"] == "fall" else 0.0)
    assert record["episode_terms"]["r_novelty"] > 0
    assert record["episode_terms"]["r_ep"] == pytest.approx(record["econ"]["energy_productivity_units_per_kwh"])
    assert record["episode_terms"]["r_ep"] > 0
