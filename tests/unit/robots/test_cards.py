"""The robot cards (econmotor/robots): the model each builds, its collision filter, its observation.

The cards' facts are held to Holosoma's own presets in .venv-holosoma
(tests/integration/test_robot_cards.py); here, in the main interpreter: the model a card builds
has the card's joints and actuators, its collision filter is Holosoma's (no robot geom can touch
another; with ``contacts="feet"`` only the feet touch the floor), and the one observation
function (:mod:`econmotor.robots.observation`) builds holosoma_inference's row, written out term by
term here, with its gait clock worked out by hand, alike in NumPy and in JAX, for one robot or a
batch ``[N, ...]`` of them (each row the robot's own, as the batched walker env relies on).
"""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
import pytest

from econmotor.errors import ConfigError
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


def _random_state(c, rng: np.random.Generator) -> dict[str, np.ndarray]:
    """A robot's state an observation is built from: any orientation, joints about the default pose."""
    quat = rng.normal(size=4)
    quat /= np.linalg.norm(quat)
    return {"quat_wxyz": quat, "ang_vel_body": rng.normal(size=3),
            "q": np.asarray(c.default_dof_angles) + rng.normal(0, 0.2, c.num_dofs),
            "qd": rng.normal(0, 2.0, c.num_dofs)}


def _by_hand(c, *, quat_wxyz, ang_vel_body, q, qd, lin_vel_cmd, ang_vel_cmd, last_action, phase) -> np.ndarray:
    """The ``actor_obs`` row written out: each term times its scale, in the card's order; gravity rotated
    into the body frame by MuJoCo's rotation matrix of the quaternion."""
    rotation = np.zeros(9)
    mujoco.mju_quat2Mat(rotation, np.asarray(quat_wxyz, dtype=np.float64))
    terms = {"actions": last_action, "base_ang_vel": ang_vel_body, "command_ang_vel": [ang_vel_cmd],
             "command_lin_vel": lin_vel_cmd, "cos_phase": np.cos(phase),
             "dof_pos": q - np.asarray(c.default_dof_angles), "dof_vel": qd,
             "projected_gravity": rotation.reshape(3, 3).T @ np.array([0.0, 0.0, -1.0]),
             "sin_phase": np.sin(phase)}
    conv = c.observation
    assert tuple(conv.terms) == tuple(sorted(terms))  # holosoma_inference concatenates its terms sorted by name
    parts = [np.asarray(terms[t], dtype=np.float64) * conv.scales[t] for t in conv.terms]
    assert [len(p) for p in parts] == [conv.dims[t] for t in conv.terms]
    return np.concatenate(parts).astype(np.float32)


#: walk, stand for three steps (both feet at pi), walk again (the clock restarts at (0, pi))
COMMANDS = [(0.8, 0.1)] * 5 + [(0.0, 0.0)] * 3 + [(0.5, -0.3)] * 4


def _expected_phase(c) -> list[tuple[tuple[float, float], bool]]:
    """The gait clock after each of :data:`COMMANDS`, worked out: (left, right) and standing."""
    dt = c.phase_dt
    walk = [((k * dt, -math.pi + k * dt), False) for k in range(1, 6)]  # right: pi + k dt wrapped into [-pi, pi)
    stand = [((math.pi, math.pi), True)] * 3
    again = [((0.0, math.pi), False)] + [((k * dt, -math.pi + k * dt), False) for k in range(1, 4)]
    return walk + stand + again


@pytest.mark.parametrize("name", NAMES)
def test_observation_is_holosomas_row_alike_in_numpy_and_jax(name: str) -> None:
    c = card(name)
    rng = np.random.default_rng(3)
    jit_obs = jax.jit(lambda **s: build_observation(c, jnp, **s))
    jit_phase = jax.jit(lambda p, st, v, w: advance_phase(p, st, v, w, c, jnp))
    phase, standing = initial_phase(np), False
    np.testing.assert_array_equal(phase, [0.0, math.pi])
    for (vx, yaw), (expected, expected_standing) in zip(COMMANDS, _expected_phase(c), strict=True):
        lin = np.array([vx, 0.0])
        phase_j, standing_j = jit_phase(jnp.asarray(phase, jnp.float32), standing, jnp.asarray(lin, jnp.float32),
                                        jnp.float32(yaw))
        phase, standing = advance_phase(phase, standing, lin, yaw, c, np)
        np.testing.assert_allclose(phase, expected, atol=1e-12)
        np.testing.assert_allclose(np.asarray(phase_j), expected, atol=1e-5)
        assert bool(standing) == expected_standing == bool(standing_j)
        state = _random_state(c, rng)
        common = {"lin_vel_cmd": lin, "ang_vel_cmd": yaw, "last_action": rng.normal(size=c.num_dofs).astype(np.float32),
                  "phase": phase}
        ours = build_observation(c, np, **state, **common)
        assert ours.dtype == np.float32 and ours.shape == (c.obs_dim,)
        np.testing.assert_allclose(ours, _by_hand(c, **state, **common), rtol=1e-6, atol=1e-6)
        ours_j = jit_obs(**{k: jnp.asarray(np.asarray(v), jnp.float32) for k, v in {**state, **common}.items()})
        np.testing.assert_allclose(np.asarray(ours_j), ours, atol=2e-6, rtol=1e-6)
    assert math.isclose(c.phase_dt, 2 * math.pi / 50.0)


@pytest.mark.parametrize("name", NAMES)
def test_a_batch_of_robots_observes_as_each_robot_alone(name: str) -> None:
    """The batched walker env builds ``[N, obs_dim]`` in one call: each row is that robot's single-robot row."""
    c = card(name)
    rng = np.random.default_rng(5)
    n = 6
    states = [_random_state(c, rng) for _ in range(n)]
    # the rows at different points of the gait clock: walking, standing, and restarting after a stand
    lin = np.array([[0.8, 0.0], [0.0, 0.0], [0.5, 0.0], [0.0, 0.0], [0.3, 0.0], [0.0, 0.0]])
    yaw = np.array([0.1, 0.0, -0.3, 0.5, 0.0, 0.005])
    before = np.stack([initial_phase(np), [0.4, -2.7], [math.pi, math.pi], [1.0, 1.5], [-3.0, 0.2], [0.1, 0.2]])
    was_standing = np.array([False, False, True, False, True, False])
    phase_b, standing_b = advance_phase(before, was_standing, lin, yaw, c, np)
    assert phase_b.shape == (n, 2) and standing_b.shape == (n,)
    np.testing.assert_array_equal(standing_b, [False, True, False, False, False, True])
    for i in range(n):
        phase_i, standing_i = advance_phase(before[i], bool(was_standing[i]), lin[i], float(yaw[i]), c, np)
        np.testing.assert_array_equal(phase_b[i], phase_i)
        assert bool(standing_b[i]) == bool(standing_i)
    batch = {k: np.stack([s[k] for s in states]) for k in states[0]}
    common = {"lin_vel_cmd": lin, "ang_vel_cmd": yaw, "phase": phase_b,
              "last_action": rng.normal(size=(n, c.num_dofs)).astype(np.float32)}
    rows = build_observation(c, np, **batch, **common)
    assert rows.dtype == np.float32 and rows.shape == (n, c.obs_dim)
    for i in range(n):
        alone = build_observation(c, np, **{k: v[i] for k, v in {**batch, **common}.items()})
        np.testing.assert_array_equal(rows[i], alone)
    rows_j = jax.jit(lambda **s: build_observation(c, jnp, **s))(
        **{k: jnp.asarray(v, jnp.float32) for k, v in {**batch, **common}.items()})
    np.testing.assert_allclose(np.asarray(rows_j), rows, atol=2e-6, rtol=1e-6)


def test_a_scaled_motor_model_puts_heat_at_the_limit_in_proportion_to_the_limit() -> None:
    from econmotor.robots.card import scaled_heat_model

    model = scaled_heat_model((100.0, 20.0), 13.0, "calibration")
    # k_j = 13 / limit: at its limit a 100 N m joint heats 1,300 W, a 20 N m one 260 W
    assert model.heat_w_per_nm2 == (pytest.approx(0.13), pytest.approx(0.65))
    assert model.heat_w_per_nm2[0] * 100.0 ** 2 == pytest.approx(1300.0)
    assert model.heat_w_per_nm2[1] * 20.0 ** 2 == pytest.approx(260.0)
    assert model.basis == "calibrated"


@pytest.mark.parametrize("name", NAMES)
def test_every_card_robot_has_a_sourced_motor_model_and_a_stated_runtime(name: str) -> None:
    c = CARDS[name]
    assert c.motor_model is not None and c.motor_model.basis in ("datasheet", "calibrated")
    assert "calibrated" in c.motor_model.source or "datasheet" in c.motor_model.source
    k = c.heat_coeff()
    assert k.shape == (c.num_dofs,) and np.all(k > 0)
    assert c.stated_runtime is not None and c.stated_runtime.hours > 0 and c.stated_runtime.source


def test_a_card_without_a_motor_model_meters_no_heat_and_a_wrong_length_is_refused() -> None:
    import dataclasses

    from econmotor.robots.card import MotorModel

    g1 = CARDS["g1_29dof"]
    assert np.all(dataclasses.replace(g1, motor_model=None).heat_coeff() == 0.0)
    with pytest.raises(ValueError, match="motor_model has 2 coefficients for 29"):
        dataclasses.replace(g1, motor_model=MotorModel((0.1, 0.1), "calibrated", "x"))
    with pytest.raises(ValueError, match="basis"):
        MotorModel((0.1,), "guessed", "x")


def test_rotate_inverse_is_the_transposed_rotation_in_numpy_and_jax() -> None:
    from econmotor.robots.observation import rotate_inverse

    rng = np.random.default_rng(3)
    quat = rng.normal(size=(8, 4))
    quat /= np.linalg.norm(quat, axis=1, keepdims=True)
    v = rng.normal(size=(8, 3))
    expected = []
    for q, x in zip(quat, v, strict=True):
        rot = np.zeros(9)
        mujoco.mju_quat2Mat(rot, q)
        expected.append(rot.reshape(3, 3).T @ x)
    np.testing.assert_allclose(rotate_inverse(quat, v, np), expected, atol=1e-12)
    one = rotate_inverse(jnp.asarray(quat[0], jnp.float32), jnp.asarray(v[0], jnp.float32), jnp)
    np.testing.assert_allclose(np.asarray(one), expected[0], atol=1e-5)
