"""One reward set for the G1/T1 walker over both engines: the MuJoCo C learner (locomotion/learning.py) pays
all of Holosoma's locomotion terms (locomotion/rewards.py), on the reading the MJX humanoid env takes.

- the batched C reading gives, robot by robot, the term values one robot's own reading gives;
- for a G1 state walked by the shipped PPO, the C learner's ten terms and reward are those of the reading
  ``humanoid_env.step`` builds (jnp, float32) from a MjData of the MJX env's model at that state: the feet
  at the start of the last physics step (what ``data.xpos``/``data.xmat`` hold after ``mjx.step``), the
  base and joints at its end, the step's command and gait clock;
- the learner accepts the feet and pose terms, and weighting ``pose`` changes its reward by the term.
"""

from __future__ import annotations

import jax.numpy as jnp
import mujoco
import numpy as np
import pytest

from econmotor.config.objective_profile import ObjectiveVector
from econmotor.couriers.policy_import import batched_onnx_policy, resolve_contract
from econmotor.locomotion import course as crs
from econmotor.locomotion import rewards as lr
from econmotor.locomotion.env import WalkerBatch
from econmotor.locomotion.learning import WalkerLearningEnv
from econmotor.locomotion.model import WalkerModel
from econmotor.locomotion.stress import Stress
from econmotor.locomotion.task import MeterSettings
from econmotor.objectives.loader import objective_from_vector
from econmotor.robots.model import joint_indices, load_model
from econmotor.robots.observation import projected_gravity, rotate_inverse
from econmotor.tasks import get_task

METER = MeterSettings(leg_distance_m=2.0, drivetrain_efficiency=0.8, idle_power_w=50.0, tilt_margin_rad=0.2,
                      fall_tilt_rad=0.8)
COURSE = crs.CourseSettings(leg_m=2.0, dwell_s=1.0, speed_m_per_s=0.8, legs=3)
OBJECTIVE = objective_from_vector(ObjectiveVector.from_preset("energy_saver"), "energy_saver")
ECONOMICS = get_task("humanoid_locomotion_g1").economics
#: Holosoma's G1 preset (``tasks/mjx.yaml``, humanoid_locomotion_g1 ``locomotion.rewards``)
G1_TERMS = {
    "tracking_lin_vel": {"weight": 2.0, "tracking_sigma": 0.25},
    "tracking_ang_vel": {"weight": 1.5, "tracking_sigma": 0.25},
    "penalty_ang_vel_xy": {"weight": -1.0}, "penalty_orientation": {"weight": -10.0},
    "penalty_action_rate": {"weight": -2.0},
    "feet_phase": {"weight": 5.0, "swing_height": 0.09, "tracking_sigma": 0.008},
    "pose": {"weight": -0.5, "pose_weights": [0.01, 1.0, 5.0, 0.01, 5.0, 5.0] * 2 + [50.0] * 17},
    "penalty_close_feet_xy": {"weight": -10.0, "close_feet_threshold": 0.15},
    "penalty_feet_ori": {"weight": -5.0}, "alive": {"weight": 1.0}}
WEIGHTS = {k: v["weight"] for k, v in G1_TERMS.items()}
PARAMS = {k: {p: x for p, x in v.items() if p != "weight"} for k, v in G1_TERMS.items()}


@pytest.fixture(scope="module")
def g1():
    return resolve_contract("holosoma:g1_29dof/ppo")


def _env(contract, n: int, weights=WEIGHTS, params=PARAMS) -> WalkerLearningEnv:
    walker = WalkerModel.build(contract.card, np.asarray(contract.kp), np.asarray(contract.kd))
    batch = WalkerBatch(walker, COURSE, METER, Stress(), 30.0, n, contract.command_ranges)
    return WalkerLearningEnv(batch, OBJECTIVE, ECONOMICS, 2.0, weights, params, seed=5)


def _walk(env: WalkerLearningEnv, policy, steps: int) -> np.ndarray:
    """``steps`` control steps of the shipped policy, driven as ``WalkerLearningEnv.step`` drives the batch but
    stopped after the last one's physics (its command and gait clock still the step's); the previous actions."""
    b, slots = env.batch, env.slots
    obs, _ = env.reset()
    for k in range(steps):
        last = b.last_action[slots].copy()
        b.act(slots, policy(obs))
        if k < steps - 1:
            obs = b.observe(slots)
    return last


def test_the_batched_reading_gives_each_robot_its_own_terms(g1) -> None:
    env = _env(g1, 4)
    b, slots = env.batch, env.slots
    last = _walk(env, batched_onnx_policy(g1), 30)
    batch = env.reading(slots, b.last_action[slots], last)
    loco, means = env._locomotion(slots, b.last_action[slots], last)
    total = np.zeros(len(slots))
    for name in lr.TERMS:
        values = np.broadcast_to(lr.TERMS[name](batch, np, **PARAMS[name]), (len(slots),))
        for i, s in enumerate(slots):
            one = env.reading(slots[i:i + 1], b.last_action[[s]], last[i:i + 1])
            alone = lr.TERMS[name](lr.LocomotionReading(*(v[0] if k != "default_q" else v for k, v in
                                                          one._asdict().items())), np, **PARAMS[name])
            assert np.ndim(alone) == 0
            np.testing.assert_allclose(values[i], alone, rtol=1e-12, err_msg=f"{name}, robot {i}")
        assert means[name] == pytest.approx(float(np.mean(values)), rel=1e-12)
        total += WEIGHTS[name] * values
    np.testing.assert_allclose(loco, total * b.card.control_dt_s, rtol=1e-12)
    assert len({round(float(v), 6) for v in np.broadcast_to(lr.feet_phase(batch, np, **PARAMS["feet_phase"]), 4)}) > 1


def _mjx_reading(card, qpos_start: np.ndarray, qpos: np.ndarray, qvel: np.ndarray, command: np.ndarray,
                 action: np.ndarray, last_action: np.ndarray, phase: np.ndarray) -> lr.LocomotionReading:
    """The reading ``humanoid_env.step`` builds of one env, from a MjData of the MJX env's model whose ``qpos``,
    ``qvel`` are the step's end and whose kinematics are of ``qpos_start``, the last physics step's start (what
    ``data`` holds after ``mjx.step``)."""
    m = load_model(card, contacts="feet")
    d = mujoco.MjData(m)
    d.qpos[:] = qpos_start
    mujoco.mj_kinematics(m, d)
    d.qpos[:], d.qvel[:] = qpos, qvel
    f32 = jnp.float32
    xpos, xmat = jnp.asarray(d.xpos, f32), jnp.asarray(d.xmat.reshape(-1, 3, 3), f32)  # mjx's xmat: (nbody, 3, 3)
    qadr = jnp.asarray(joint_indices(m, card)[0])
    feet = jnp.asarray([m.body(b).id for b in card.foot_bodies])
    points = jnp.asarray([m.body(b).id for b in card.foot_contact_bodies])
    qpos, qvel = jnp.asarray(d.qpos, f32), jnp.asarray(d.qvel, f32)
    quat = qpos[3:7]
    return lr.LocomotionReading(
        command=jnp.asarray(command, f32), lin_vel_body=rotate_inverse(quat, qvel[0:3], jnp), ang_vel_body=qvel[3:6],
        gravity_body=projected_gravity(quat, jnp), action=jnp.asarray(action, f32),
        last_action=jnp.asarray(last_action, f32), q=qpos[qadr], default_q=jnp.asarray(card.default_dof_angles, f32),
        phase=jnp.asarray(phase, f32), foot_z=xpos[points, 2], feet_xy=xpos[feet, 0:2],
        feet_gravity_xy=-xmat[feet, 2, 0:2], base_yaw=crs.heading_yaw(quat, jnp))


def test_the_c_learner_pays_the_mjx_envs_terms_for_a_g1_state(g1) -> None:
    env = _env(g1, 2)
    b, slots = env.batch, env.slots
    last = _walk(env, batched_onnx_policy(g1), 40)
    states, _ = b._record  # each slot's qpos and qvel after each physics step of the last control step
    nq, nv = b.nq, b.nv
    checked = 0
    for i, s in enumerate(slots):
        loco, terms = env._locomotion(slots[i:i + 1], b.last_action[[s]], last[i:i + 1])
        state = b.state[s]
        command = np.array([b.command[s, 0], 0.0, b.command[s, 1]])
        reading = _mjx_reading(g1.card, states[s, -2, 1:1 + nq], state[1:1 + nq], state[1 + nq:1 + nq + nv],
                               command, b.last_action[s], last[i], b.phase[s])
        total, raw = lr.locomotion_reward(reading, WEIGHTS, PARAMS, b.card.control_dt_s, jnp)
        assert set(terms) == set(raw) == set(lr.TERMS)
        for name in lr.TERMS:
            assert terms[name] == pytest.approx(float(raw[name]), rel=2e-4, abs=2e-5), name
        assert float(loco[0]) == pytest.approx(float(total), rel=2e-4, abs=2e-5)
        checked += 1
    assert checked == 2


def test_the_learner_pays_the_pose_term(g1) -> None:
    base = {"tracking_lin_vel": 2.0, "alive": 1.0}
    plain = _env(g1, 2, base, {})
    posed = _env(g1, 2, {**base, "pose": -0.5, "feet_phase": 0.0, "penalty_close_feet_xy": 0.0,
                         "penalty_feet_ori": 0.0}, {"pose": PARAMS["pose"]})
    policy = batched_onnx_policy(g1)
    obs, _ = plain.reset()
    posed.reset()
    for _ in range(10):
        action = policy(obs)
        a, p = plain.step(action), posed.step(action)
        obs = a.obs
        np.testing.assert_array_equal(a.obs, p.obs)  # the same robots, the same actions
    assert p.terms["pose"] > 0
    assert {"feet_phase", "penalty_close_feet_xy", "penalty_feet_ori"} <= set(p.terms)
    pose = np.mean(p.reward - a.reward) / (-0.5 * plain.batch.card.control_dt_s)
    assert pose == pytest.approx(p.terms["pose"], rel=1e-9)
    assert np.all(p.reward < a.reward)
