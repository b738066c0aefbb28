"""``cpu_physics: mujoco``: the mjx couriers' physics stepped by MuJoCo C from the jitted step (host_physics.py).

The host-stepped hopper agrees with the MJX one step by step (same model, float32 state); the episode's
friction and mass multipliers reach MuJoCo C as they reach MJX and leave the model as it was; a state MuJoCo
rejects comes back NaN (a fall), not silently reset; concurrent callers (training, the evaluator beside it)
get the results each would get alone; a body whose readouts MuJoCo C does not return is refused by name.
"""

from __future__ import annotations

import threading

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
import pytest

from econmotor.errors import ConfigError
from econmotor.motor_backend.mjx.env import GymCourierEnv
from econmotor.motor_backend.mjx.host_physics import HostData, HostPhysics
from econmotor.motor_backend.mjx.settings import parse_mjx_settings

from .conftest import NUM_ENVS, catalog_with_mjx_entry


def _actions(steps: int, seed: int = 0) -> np.ndarray:
    return np.random.default_rng(seed).uniform(-1.0, 1.0, (steps, NUM_ENVS, 3)).astype(np.float32)


def test_host_steps_the_hopper_as_mjx_does(hopper, hopper_host):
    """80 control steps (falls and auto-resets among them) of random actions: states, observations, rewards,
    falls and the meter's readings agree with MJX's to float32's precision."""
    assert hopper_host.env.unwrapped.host is not None and hopper.env.unwrapped.host is None
    key = jax.random.PRNGKey(3)
    a, b = hopper.reset(key, NUM_ENVS), hopper_host.reset(key, NUM_ENVS)
    falls = 0
    for action in map(jnp.asarray, _actions(80)):  # jax arrays, as every test of the shared env steps it
        a, b = jax.block_until_ready(hopper.step(a, action)), jax.block_until_ready(hopper_host.step(b, action))
        np.testing.assert_allclose(b.data.qpos, a.data.qpos, atol=2e-4)
        np.testing.assert_allclose(b.obs, a.obs, atol=2e-3)
        np.testing.assert_allclose(b.reward, a.reward, rtol=1e-3, atol=1e-3)
        np.testing.assert_array_equal(b.done, a.done)
        np.testing.assert_allclose(b.readings["mechanical_w"], a.readings["mechanical_w"], rtol=1e-3, atol=1e-2)
        falls += int(np.sum(a.done))
    assert falls > 0  # the comparison crossed falls and auto-resets


def _physics() -> tuple[HostPhysics, mujoco.MjModel]:
    env = GymCourierEnv("hopper_courier", physics="mujoco")
    return env.host, env.mj_model


def _c_step(model: mujoco.MjModel, qpos: np.ndarray, qvel: np.ndarray, ctrl: np.ndarray, n: int) -> np.ndarray:
    d = mujoco.MjData(model)
    d.qpos[:], d.qvel[:], d.ctrl[:] = qpos, qvel, ctrl
    mujoco.mj_step(model, d, nstep=n)
    return d.qpos.copy()


def test_randomized_episodes_step_their_own_model_and_leave_it_as_it_was():
    host, model = _physics()
    qpos = model.qpos0 + np.array([0.0, 0.0, 0.05, -0.1, 0.1, 0.05])
    qvel, ctrl = np.full(model.nv, 0.3), np.array([0.8, -0.6, 0.4])
    mass = np.linspace(0.6, 1.6, model.nbody)
    mass[0] = 1.0
    draws = {"friction_scale": jnp.float32(0.3), "mass_scale": jnp.asarray(mass, jnp.float32)}
    state = HostData(jnp.asarray(qpos, jnp.float32), jnp.asarray(qvel, jnp.float32),
                     jnp.zeros(model.nv, jnp.float32), jnp.zeros(model.nv, jnp.float32))
    moved = host.step(state, jnp.asarray(ctrl, jnp.float32), draws)
    changed = _copy_with(model, 0.3, mass)
    expected = _c_step(changed, state.qpos, state.qvel, ctrl, host.frame_skip)
    np.testing.assert_allclose(moved.qpos, expected, atol=1e-5)
    plain = host.step(state, jnp.asarray(ctrl, jnp.float32), {})
    np.testing.assert_allclose(plain.qpos, _c_step(model, state.qpos, state.qvel, ctrl, host.frame_skip), atol=1e-5)
    assert np.max(np.abs(np.asarray(plain.qpos) - expected)) > 1e-4  # the draws did change the step


def _copy_with(model: mujoco.MjModel, friction: float, mass: np.ndarray) -> mujoco.MjModel:
    import copy

    changed = copy.copy(model)
    changed.geom_friction[:, 0] *= friction
    changed.body_mass[:] *= mass
    changed.body_inertia[:] *= mass[:, None]
    return changed


def test_a_state_mujoco_rejects_comes_back_nan_and_reads_as_a_fall(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # MuJoCo appends its warning to MUJOCO_LOG.TXT in the working directory
    host, model = _physics()
    qpos = np.stack([model.qpos0, model.qpos0]).astype(np.float32)
    qvel = np.zeros((2, model.nv), np.float32)
    qvel[1] = 1e12  # MuJoCo C's mjWARN_BADQACC: it would reset this one to qpos0 and carry on
    zeros = jnp.zeros((2, model.nv), jnp.float32)
    out = jax.vmap(lambda q, v, w, f: host.step(HostData(q, v, w, f), jnp.zeros(3), {}))(
        jnp.asarray(qpos), jnp.asarray(qvel), zeros, zeros)
    assert np.all(np.isfinite(out.qpos[0])) and np.all(np.isnan(out.qpos[1]))
    from econmotor.robots import gym_couriers as robots

    env = GymCourierEnv("hopper_courier", physics="mujoco")
    assert not bool(robots.is_healthy(env.healthy, out.qpos[1], out.qvel[1], jnp))


def test_concurrent_callers_get_what_each_gets_alone(hopper_host):
    """Training and the held-out evaluator step one env's physics from two threads at once."""
    keys = [jax.random.PRNGKey(k) for k in (11, 12)]
    actions = [_actions(40, seed) for seed in (1, 2)]

    def roll(i: int, out: list) -> None:
        s = hopper_host.reset(keys[i], NUM_ENVS)
        for action in actions[i]:
            s = hopper_host.step(s, jnp.asarray(action))
        out[i] = np.asarray(jax.block_until_ready(s).data.qpos)

    alone: list = [None, None]
    for i in range(2):
        roll(i, alone)
    together: list = [None, None]
    threads = [threading.Thread(target=roll, args=(i, together)) for i in range(2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    for i in range(2):
        np.testing.assert_array_equal(together[i], alone[i])


def test_cpu_physics_is_validated_by_name():
    catalog = catalog_with_mjx_entry("hopper_courier", "tasks/x.yaml", cpu_physics="bullet")
    with pytest.raises(ConfigError) as err:
        parse_mjx_settings(catalog.get("hopper_courier"))
    assert "cpu_physics" in str(err.value) and "tasks/x.yaml" in str(err.value) and "mujoco" in str(err.value)
    assert parse_mjx_settings(catalog_with_mjx_entry("ant_courier").get("ant_courier")).cpu_physics == "mjx"


def test_a_body_mujoco_c_cannot_read_for_is_refused():
    """The ant's observation holds contact forces, which the host step does not return."""
    with pytest.raises(ConfigError) as err:
        GymCourierEnv("ant_courier", physics="mujoco")
    assert "cpu_physics" in str(err.value) and "cfrc_ext" in str(err.value)


def test_a_robot_cards_courier_cannot_step_in_mujoco_c():
    """The G1's mjx courier reads MJX data (its PD, contacts, course): ``cpu_physics: mujoco`` is refused."""
    catalog = catalog_with_mjx_entry("humanoid_locomotion_g1", "tasks/x.yaml", cpu_physics="mujoco")
    with pytest.raises(ConfigError) as err:
        parse_mjx_settings(catalog.get("humanoid_locomotion_g1"))
    assert "cpu_physics" in str(err.value) and "robot card" in str(err.value)


def test_control_steps_continue_one_mujoco_c_trajectory():
    """Control step after control step, the host's state (its solver warm start included) continues what one
    ``MjData`` stepped without a break would do, to float32's rounding of the carried state. The walker's feet
    make its solver start matter (started from zero each control step, its trajectory parts by metres)."""
    env = GymCourierEnv("walker_courier", physics="mujoco")
    host, model = env.host, env.mj_model
    d = mujoco.MjData(model)
    state = host.template()
    step = jax.jit(lambda s, a: host.step(s, a, {}))
    for action in np.random.default_rng(5).uniform(-1.0, 1.0, (100, model.nu)).astype(np.float32):
        state = step(state, jnp.asarray(action))
        d.ctrl[:] = action
        mujoco.mj_step(model, d, nstep=host.frame_skip)
        np.testing.assert_allclose(state.qpos, d.qpos, atol=5e-4)  # carried: <= 7e-5; from zero: 2e-2 by step 100
