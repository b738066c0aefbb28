"""The robot cards (econmotor/robots): the model each builds, its collision filter, its observation.

The cards' facts are held to Holosoma's own presets in .venv-holosoma
(tests/integration/test_robot_cards.py); here, in the main interpreter: the model a card builds
has the card's joints and actuators, its collision filter is Holosoma's (no robot geom can touch
another; with ``contacts="feet"`` only the feet touch the floor), and the one observation
function gives the same row in NumPy and in JAX as the sim-to-sim evaluator's builder.
"""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
import pytest

from econmotor.errors import ConfigError
from econmotor.motor_backend.holosoma.policy_import import PolicyContract
from econmotor.motor_backend.holosoma.sim2sim import ObservationBuilder
from econmotor.robots import CARDS, card
from econmotor.robots.model import FLOOR, joint_indices, load_model, mjcf_path
from econmotor.robots.observation import advance_phase, build_observation, initial_phase

NAMES = sorted(CARDS)


def colliding_pairs(model: mujoco.MjModel) -> set[tuple[str, str]]:
    """Geom pairs (by body for robot geoms) whose contype/conaffinity let them collide."""
    out = set()
    for a in range(model.ngeom):
        for b in range(a + 1, model.ngeom):
            ta, tb = model.geom_contype[a], model.geom_contype[b]
            if (ta & model.geom_conaffinity[b]) or (tb & model.geom_conaffinity[a]):
                out.add((model.geom(a).name or f"#{a}", model.geom(b).name or f"#{b}"))
    return out


@pytest.mark.parametrize("name", NAMES)
def test_model_has_the_cards_joints_and_holosomas_collision_filter(name: str) -> None:
    c = card(name)
    m = load_model(c)
    qadr, _, act = joint_indices(m, c)
    assert len(set(qadr.tolist())) == len(set(act.tolist())) == c.num_dofs
    assert m.opt.timestep == pytest.approx(c.physics_dt_s)
    assert m.nmesh == 0  # visual meshes dropped: the evaluator and MJX need no mesh files
    pairs = colliding_pairs(m)
    assert pairs and all(FLOOR in p for p in pairs)  # robot geoms collide with the floor only
    robot = m.geom_bodyid != 0
    assert np.all(m.geom_contype[robot & (m.geom_contype > 0)] == 1)


@pytest.mark.parametrize("name", NAMES)
def test_feet_contacts_let_only_the_feet_touch_the_floor(name: str) -> None:
    c = card(name)
    m = load_model(c, contacts="feet")
    touching = {a if b == FLOOR else b for a, b in colliding_pairs(m)}
    assert touching == set(c.foot_geoms)
    for p in range(m.npair):
        assert {m.geom(int(m.pair_geom1[p])).name, m.geom(int(m.pair_geom2[p])).name} <= set(c.foot_geoms) | {FLOOR}


def test_unknown_robot_and_missing_package_are_clear_errors() -> None:
    with pytest.raises(ConfigError, match="g1_29dof"):
        card("g2")
    from dataclasses import replace

    with pytest.raises(ConfigError, match="pip install"):
        mjcf_path(replace(card("g1_29dof"), mjcf_package="no_such_robot_package"))


def contract_of(c) -> PolicyContract:
    """The sim-to-sim evaluator's contract with the card's facts (its observation builder reads these)."""
    conv = c.observation
    return PolicyContract(
        policy=c.name, onnx_path="", input_name="actor_obs", obs_dim=c.obs_dim, action_dim=c.num_dofs,
        dof_names=c.dof_names, kp=c.kp, kd=c.kd, default_dof_angles=c.default_dof_angles,
        effort_limits=c.effort_limits, action_scale=c.action_scale, action_clip=c.action_clip,
        command_ranges={k: list(v) for k, v in c.command_ranges.items()}, obs_terms=conv.terms,
        obs_dims=dict(conv.dims), obs_scales=dict(conv.scales), history_length=conv.history_length,
        use_phase=conv.use_phase, gait_period_s=conv.gait_period_s, control_rate_hz=c.control_rate_hz,
        physics_dt_s=c.physics_dt_s, decimation=c.decimation, init_pos=c.init_pos, xml_path=str(mjcf_path(c)),
        torso_body=c.torso_body, inference_preset=c.inference_preset, experiment=c.holosoma_experiment)


@pytest.mark.parametrize("name", NAMES)
def test_observation_in_numpy_and_jax_equals_the_evaluators(name: str) -> None:
    c = card(name)
    builder = ObservationBuilder(contract_of(c))
    rng = np.random.default_rng(3)
    jit_obs = jax.jit(lambda **s: build_observation(c, jnp, **s))
    jit_phase = jax.jit(lambda p, st, v, w: advance_phase(p, st, v, w, c, jnp))
    phase, standing = initial_phase(np), False
    # walk, stand for three steps (both feet at pi), walk again (the clock restarts at (0, pi))
    commands = [(0.8, 0.1)] * 5 + [(0.0, 0.0)] * 3 + [(0.5, -0.3)] * 4
    for vx, yaw in commands:
        lin = np.array([vx, 0.0])
        builder.advance_phase(lin, yaw)
        phase_j, standing_j = jit_phase(jnp.asarray(phase, jnp.float32), standing, jnp.asarray(lin, jnp.float32),
                                        jnp.float32(yaw))
        phase, standing = advance_phase(phase, standing, lin, yaw, c, np)
        np.testing.assert_allclose(phase, builder.phase, atol=1e-12)
        np.testing.assert_allclose(np.asarray(phase_j), builder.phase, atol=1e-5)
        assert bool(standing) == builder.standing == bool(standing_j)
        quat = rng.normal(size=4)
        quat /= np.linalg.norm(quat)
        state = {"quat_wxyz": quat, "ang_vel_body": rng.normal(size=3),
                 "q": np.asarray(c.default_dof_angles) + rng.normal(0, 0.2, c.num_dofs),
                 "qd": rng.normal(0, 2.0, c.num_dofs)}
        builder.last_action = rng.normal(size=c.num_dofs).astype(np.float32)
        theirs = builder.build(lin_vel_cmd=lin, ang_vel_cmd=yaw, **state)[0]
        common = {"lin_vel_cmd": lin, "ang_vel_cmd": yaw, "last_action": builder.last_action, "phase": phase}
        ours = build_observation(c, np, **state, **common)
        assert ours.dtype == np.float32 and ours.shape == (c.obs_dim,)
        np.testing.assert_array_equal(ours, theirs)
        ours_j = jit_obs(**{k: jnp.asarray(np.asarray(v), jnp.float32) for k, v in {**state, **common}.items()})
        np.testing.assert_allclose(np.asarray(ours_j), theirs, atol=2e-6, rtol=1e-6)
    assert math.isclose(c.phase_dt, 2 * math.pi / 50.0)
