"""The robot cards' PD law written once (:func:`econmotor.locomotion.model.pd_actuator_spec`), in both engines.

- the MJX humanoid env's model carries the actuators of ``pd_actuator_spec`` (feet-only contacts), the
  same as the MuJoCo C walker env's (:class:`~econmotor.locomotion.model.WalkerModel`): gain ``kp``,
  bias ``(0, -kp, -kd)``, force range the card's effort limits, gear 1, no control range;
- the episode's kp/kd scales go into those actuators (:meth:`HumanoidWalkerEnv.randomized_model`,
  :func:`~econmotor.locomotion.model.pd_gain_bias`);
- for one state, the law's joint torque (``qfrc_actuator``) is MuJoCo C's (``mj_forward``), MJX's (the
  stages of ``mjx.step`` that compute it) and the formula's ``clip(kp (target - q) - kd qd, -limit, limit)``.

That the MJX step writes the PD targets (not torques) into ``ctrl`` is checked with the step itself, in
``test_humanoid_env.py``'s parity test.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
import pytest

from econmotor.config.datapacks import DatapackBundle
from econmotor.locomotion.model import WalkerModel, pd_actuator_spec, set_pd_gains
from econmotor.motor_backend.mjx._mjx import mjx
from econmotor.motor_backend.mjx.assets import apply_model_options
from econmotor.robots.model import joint_indices

TASKS = {"g1_29dof": "humanoid_locomotion_g1", "t1_29dof": "humanoid_locomotion_t1"}
#: the actuator fields the law lives in
PD_FIELDS = ("actuator_gaintype", "actuator_biastype", "actuator_gainprm", "actuator_biasprm", "actuator_forcerange",
             "actuator_forcelimited", "actuator_ctrllimited", "actuator_gear", "actuator_trntype", "actuator_trnid",
             "actuator_dyntype")


def env_of(robot: str, gains: bool = True):
    """The MJX humanoid env of ``robot`` (kp/kd scale ranges from a datapack when ``gains``)."""
    from econmotor.motor_backend.mjx.humanoid_env import HumanoidWalkerEnv

    task = TASKS[robot]
    pack = DatapackBundle(task_id=task, datapack_ids=("p",), domain_randomization={"kp_range": [0.8, 1.2],
                          "kd_range": [0.5, 1.5]}, sources={"p": "packs/p.yaml"})
    return HumanoidWalkerEnv(task, datapacks=[pack] if gains else [])


def scales(n: int) -> dict[str, jax.Array]:
    return {"kp_scale": jnp.linspace(0.8, 1.2, n), "kd_scale": jnp.linspace(1.5, 0.5, n)}


@pytest.mark.parametrize("robot", sorted(TASKS))
def test_the_mjx_humanoid_model_has_the_pd_actuators_of_pd_actuator_spec(robot: str) -> None:
    env = env_of(robot, gains=False)
    card, m = env.card, env.mj_model
    _, _, act = joint_indices(m, card)
    assert m.nu == len(act) == card.num_dofs
    assert np.all(m.actuator_gaintype[act] == mujoco.mjtGain.mjGAIN_FIXED)
    assert np.all(m.actuator_biastype[act] == mujoco.mjtBias.mjBIAS_AFFINE)
    np.testing.assert_array_equal(m.actuator_gainprm[act, 0], card.array("kp"))
    np.testing.assert_array_equal(m.actuator_biasprm[act, :3],
                                  np.stack([0.0 * card.array("kp"), -card.array("kp"), -card.array("kd")], 1))
    limit = card.array("effort_limits")
    np.testing.assert_array_equal(m.actuator_forcerange[act], np.stack([-limit, limit], 1))
    assert np.all(m.actuator_forcelimited[act]) and not np.any(m.actuator_ctrllimited[act])
    assert np.all(m.actuator_gear[act, 0] == 1.0)  # qfrc_actuator (the meter's) is the joint torque
    # built by pd_actuator_spec (feet-only contacts, the task's model options), as the C walker env's model is
    ref = pd_actuator_spec(card, card.array("kp"), card.array("kd"), contacts="feet").compile()
    apply_model_options(ref, env.settings.model_options)
    walker = WalkerModel.build(card).model
    for field in PD_FIELDS:
        np.testing.assert_array_equal(getattr(m, field), getattr(ref, field), err_msg=field)
        np.testing.assert_array_equal(getattr(m, field), getattr(walker, field), err_msg=field)
    assert m.opt.integrator == mujoco.mjtIntegrator.mjINT_EULER  # kd explicit, as when the law was outside
    np.testing.assert_allclose(np.asarray(env.model.actuator_gainprm), m.actuator_gainprm, rtol=1e-7)


def test_the_episodes_gains_go_into_the_actuators() -> None:
    env = env_of("t1_29dof")
    card, n = env.card, env.card.num_dofs
    act = np.asarray(env._act)
    draws = scales(n)
    m = env.randomized_model(draws)
    kp = card.array("kp") * np.asarray(draws["kp_scale"])
    kd = card.array("kd") * np.asarray(draws["kd_scale"])
    np.testing.assert_allclose(np.asarray(m.actuator_gainprm)[act, 0], kp, rtol=1e-6)
    np.testing.assert_allclose(np.asarray(m.actuator_biasprm)[act, 1:3], np.stack([-kp, -kd], 1), rtol=1e-6)
    np.testing.assert_array_equal(np.asarray(env.model.actuator_gainprm)[act, 0], card.array("kp"))  # left as it was


@pytest.mark.parametrize("robot", sorted(TASKS))
def test_one_law_gives_one_torque_in_both_engines(robot: str) -> None:
    """A state off the default pose, moving, with targets some of which saturate the effort limits."""
    env = env_of(robot)
    card, n = env.card, env.card.num_dofs
    draws = scales(n)
    kp, kd = card.array("kp") * np.asarray(draws["kp_scale"]), card.array("kd") * np.asarray(draws["kd_scale"])
    limit = card.array("effort_limits")
    rng = np.random.default_rng(7)
    # MuJoCo C: the PD-actuated model, the episode's gains set by set_pd_gains, the targets in ctrl
    model = pd_actuator_spec(card, card.array("kp"), card.array("kd"), contacts="feet").compile()
    apply_model_options(model, env.settings.model_options)
    qadr, dadr, act = joint_indices(model, card)
    set_pd_gains(model, act, kp, kd)
    data = mujoco.MjData(model)
    data.qpos[:] = np.asarray(env._qpos0, np.float64)
    data.qpos[qadr] += rng.uniform(-0.1, 0.1, n)
    data.qvel[:] = rng.uniform(-2.0, 2.0, model.nv)
    target = card.array("default_dof_angles") + rng.uniform(-0.4, 0.4, n)
    data.qpos[:], data.qvel[:], target = (np.float32(x).astype(np.float64) for x in (data.qpos, data.qvel, target))
    data.ctrl[act] = target
    mujoco.mj_forward(model, data)
    c_tau = data.qfrc_actuator[dadr].copy()
    q, qd = data.qpos[qadr], data.qvel[dadr]
    law = np.clip(kp * (target - q) - kd * qd, -limit, limit)
    assert 0 < np.sum(np.abs(law) == limit) < n  # some joints at their limit, some not
    np.testing.assert_allclose(c_tau, law, rtol=1e-12, atol=1e-9)
    # MJX: the env's model for the episode, the same state; qfrc_actuator as mjx.step computes it
    m = env.randomized_model(draws)
    d = env._template.replace(qpos=jnp.asarray(data.qpos, jnp.float32), qvel=jnp.asarray(data.qvel, jnp.float32),
                              ctrl=env._template.ctrl.at[env._act].set(jnp.asarray(target, jnp.float32)))

    @jax.jit
    def actuation(m, d):
        return mjx.fwd_actuation(m, mjx.fwd_velocity(m, mjx.fwd_position(m, d))).qfrc_actuator

    mjx_tau = np.asarray(actuation(m, d))[dadr]
    np.testing.assert_allclose(mjx_tau, c_tau, rtol=1e-5, atol=1e-3)  # float32 against float64 (N m)
