"""Per-step metering parity: MuJoCo C (the mujoco backend's meter) vs MJX from the same state.

Every step, the C env's state (qpos, qvel, warm start, time) is copied into the MJX env with the
episode's running sums at zero, both step the same action, and the step's units, energy, fall,
risk, task reward and observation are compared. The MJX side runs in float32, the C side in
float64, on the same model: the MJX adjustments and the task's ``model_options`` (Euler, few
solver iterations, feet-only contacts; see mjx/assets.py) are applied to the C side too.

Stated tolerances (measured worst cases are several times smaller):

- units per step: 2e-6 legs absolute (x to ~2e-5 m in float32),
- energy per step: 1e-4 relative + 1e-9 Wh absolute,
- falls: identical,
- risk per step and the task reward: 1e-4 relative / 1e-4 absolute,
- observations: 1e-3 absolute + 1e-3 relative (humanoid's contact forces: see the test).
"""

from __future__ import annotations

import gymnasium as gym
import jax
import jax.numpy as jnp
import mujoco
import numpy as np
import pytest

from econmotor.motor_backend.mjx.assets import apply_model_options
from econmotor.motor_backend.mujoco.metering import EconomicMeteringWrapper

from .conftest import NUM_ENVS


def c_metered_env(env):
    """The mujoco backend's meter on the same Gymnasium env and model options as ``env`` (a batched GymCourierEnv)."""
    s = env.settings
    base = gym.make(s.env_id, **s.env_kwargs)
    apply_model_options(base.unwrapped.model, s.model_options)  # the model MJX runs, on the C side too
    return EconomicMeteringWrapper(base, s.leg_distance_m, s.drivetrain_efficiency, s.idle_power_w, s.tilt_margin_rad,
                                   s.fall_tilt_rad, s.novelty_dims, s.novelty_bin)


def state_from_c(state, meter):
    """``state`` with every env's physics set to the C env's and the episode's sums at zero."""
    c = meter.unwrapped.data
    n = state.obs.shape[0]

    def batch(x):
        return jnp.broadcast_to(jnp.asarray(np.asarray(x), jnp.float32), (n, *np.shape(x)))

    # xpos / xipos: the task reward's x before the step (ant: the torso, humanoid: the mass centre)
    # reads the kinematics the last step left, as Gymnasium does
    data = state.data.replace(qpos=batch(c.qpos), qvel=batch(c.qvel), qacc_warmstart=batch(c.qacc_warmstart),
                              time=batch(c.time), xpos=batch(c.xpos), xipos=batch(c.xipos))
    episode = {k: jnp.zeros_like(v) for k, v in state.episode.items()}
    episode["best_x"] = batch(meter.episode.best_x)
    episode["x0"] = batch(meter.x0)
    return state._replace(data=data, episode=episode)


def run_parity(jitted, steps: int, seed: int, obs_atol: float, skip_obs_from: int | None = None) -> dict[str, float]:
    env = jitted.env
    meter = c_metered_env(env)
    obs_c, _ = meter.reset(seed=seed)
    state = jitted.reset(jax.random.PRNGKey(seed), NUM_ENVS)
    rng = np.random.default_rng(seed)
    worst = {"units": 0.0, "energy_rel": 0.0, "obs": 0.0}
    falls = 0
    for t in range(steps):
        state = state_from_c(state, meter)
        action = rng.uniform(env.action_low, env.action_high).astype(np.float32)
        before = meter.episode
        units0, wh0, risk0 = before.units, before.energy_wh, before.risk_sum
        obs_c, reward_c, terminated, truncated, _ = meter.step(action.astype(np.float64))
        tally = meter.episode
        state = jitted.step(state, jnp.broadcast_to(jnp.asarray(action), (NUM_ENVS, env.action_size)))
        f = {k: np.asarray(v)[0] for k, v in state.finished.items()}
        assert f["length_steps"] == 1.0
        assert bool(f["fell"]) == bool(terminated), f"step {t}: fall differs"
        assert float(np.asarray(state.done)[0]) == float(terminated or truncated)
        assert f["units_completed"] == pytest.approx(tally.units - units0, abs=2e-6), t
        assert f["energy_wh"] == pytest.approx(tally.energy_wh - wh0, rel=1e-4, abs=1e-9), t
        assert f["risk_score"] == pytest.approx(tally.risk_sum - risk0, rel=1e-4, abs=1e-4), t
        assert f["return"] == pytest.approx(reward_c, rel=1e-4, abs=1e-4), t
        worst["units"] = max(worst["units"], abs(f["units_completed"] - (tally.units - units0)))
        worst["energy_rel"] = max(worst["energy_rel"], abs(f["energy_wh"] / (tally.energy_wh - wh0) - 1.0))
        if terminated or truncated:
            falls += int(terminated)
            obs_c, _ = meter.reset(seed=seed + 1000 + t)
            continue
        obs_j = np.asarray(state.obs)[0]
        cols = slice(None, skip_obs_from)
        np.testing.assert_allclose(obs_j[cols], obs_c[cols], atol=obs_atol, rtol=1e-3, err_msg=f"step {t}")
        worst["obs"] = max(worst["obs"], float(np.max(np.abs(obs_j[cols] - obs_c[cols]))))
    worst["falls"] = falls
    return worst


def test_hopper_meters_the_same_per_step_as_mujoco_c(hopper):
    worst = run_parity(hopper, steps=120, seed=0, obs_atol=1e-3)
    assert worst["falls"] >= 1  # a fall was compared (random actions topple the hopper)


def test_humanoid_meters_the_same_per_step_as_mujoco_c(humanoid):
    env = humanoid.env
    assert env.mj_model.opt.solver == mujoco.mjtSolver.mjSOL_NEWTON
    # the observation's tail is cfrc_ext (contact forces): compared through the task reward's
    # contact cost instead, where the solvers' float32/float64 differences average out
    n_cfrc = 6 * (env.mj_model.nbody - 1)
    worst = run_parity(humanoid, steps=40, seed=1, obs_atol=2e-3, skip_obs_from=env.observation_size - n_cfrc)
    assert worst["falls"] >= 1
