"""The G1 and T1 couriers on MJX (mjx/humanoid_env.py): MuJoCo C parity, Holosoma's convention, a shipped walker.

- Parity: every control step the C model's state (the card's model with the task's
  ``model_options``, as MJX runs it, the solver run to convergence; the T1's under the stress
  datapack, its draws applied to both) is copied into the MJX env,
  both apply the same action through Holosoma's PD loop (the PD targets in ``ctrl``, the law in the
  actuators of :func:`econmotor.locomotion.model.pd_actuator_spec`, the episode's gains set in both),
  and the step's physics, metering (the sim-to-sim evaluator's meter, ``WalkerBatch._meter``, on
  the C side's physics steps) and next observation (the evaluator's ``WalkerBatch.observe`` on the
  C state: its course command, gait clock and observation) are compared. Float32 MJX vs float64 C:
  stated tolerances in the test.
- Holosoma's shipped G1 PPO walker (its ONNX, run by onnxruntime) driven by the MJX G1 env, on
  the catalog's model options (the ones training runs), walks: no fall over a short episode, and
  its speed is within 15% of what the sim-to-sim evaluator (the batched MuJoCo walker env,
  ``locomotion.evaluation``, in this interpreter) measures on the same course.

One jitted env per robot and model options for the whole module (compiling a humanoid's step
takes minutes of CPU); its episode is short (:data:`EPISODE_S`) so the walker's episode ends at its step limit.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
import pytest

from econmotor.couriers.policy_import import resolve_contract
from econmotor.economics.termination import TerminationReason
from econmotor.locomotion.env import WalkerBatch
from econmotor.locomotion.evaluation import WalkerEvaluation, evaluate
from econmotor.locomotion.model import WalkerModel, pd_actuator_spec, set_pd_gains
from econmotor.locomotion.stress import Stress
from econmotor.locomotion.task import MeterSettings
from econmotor.motor_backend.mjx.assets import apply_model_options
from econmotor.robots.model import joint_indices

from .conftest import JittedEnv, catalog_with_mjx_entry

REPO = Path(__file__).resolve().parents[4]
EPISODE_S = 6.0
TASKS = {"g1_29dof": "humanoid_locomotion_g1", "t1_29dof": "humanoid_locomotion_t1"}
_ENVS: dict[str, JittedEnv] = {}


def stress_bundle(task: str):
    """The stress datapack (``humanoid_stress.yaml``: friction, payload, pushes, start noise) plus
    kp/kd ranges, as the backend hands datapacks to the env."""
    from econmotor.config.datapacks import DatapackBundle, load_datapack_configs

    [pack] = load_datapack_configs([REPO / "configs" / "datapacks" / "humanoid_stress.yaml"])
    dr = {**pack.domain_randomization, "kp_range": [0.9, 1.1], "kd_range": [0.8, 1.2]}
    return DatapackBundle(task_id=task, datapack_ids=(pack.id,), domain_randomization=dr,
                          sources={pack.id: pack.source})


def humanoid(robot: str, stress: bool = False, **model_options) -> JittedEnv:
    """The module's env of ``robot`` (episode :data:`EPISODE_S`; ``model_options`` over the catalog's;
    ``stress``: the :func:`stress_bundle` datapack), built and jitted once."""
    key = (robot, stress, *sorted(model_options.items()))
    if key not in _ENVS:
        from econmotor.motor_backend.mjx.humanoid_env import HumanoidWalkerEnv
        from econmotor.motor_backend.mjx.wrappers import make_env
        from econmotor.objectives import EconomicObjectiveSpec
        from econmotor.tasks.catalog import TaskCatalog, load_catalog

        task = TASKS[robot]
        entry = load_catalog().get(task).backends["mjx"]
        changes = {"model_options": {**entry["model_options"], **model_options}} if model_options else {}
        spec = catalog_with_mjx_entry(task, **changes).get(task)
        spec = replace(spec, locomotion={**spec.locomotion, "sim2sim_episode_s": EPISODE_S})  # the time limit
        objective = EconomicObjectiveSpec(mpl_weight=1.0, energy_weight=0.5, error_weight=0.2, risk_weight=0.4)
        _ENVS[key] = JittedEnv(make_env(HumanoidWalkerEnv, task, objective=objective,
                                          datapacks=[stress_bundle(task)] if stress else [],
                                          catalog=TaskCatalog({task: spec})))
    return _ENVS[key]


def c_robot(env, draws):
    """MuJoCo C on the model the MJX env runs: the card's with the PD law in its actuators, feet-only
    contacts, the task's model options, and the episode's stress ``draws`` (floor friction unless None,
    torso payload, kp/kd scales)."""
    card = env.card
    model = pd_actuator_spec(card, card.array("kp"), card.array("kd"), contacts="feet").compile()
    apply_model_options(model, env.settings.model_options)
    if draws["friction"] is not None:
        model.geom_friction[model.geom("floor").id, 0] = draws["friction"]
        model.pair_friction[:, 0:2] = draws["friction"]
    model.body_mass[model.body(card.torso_body).id] += draws["payload_kg"]
    data = mujoco.MjData(model)
    qadr, dadr, act = joint_indices(model, card)
    set_pd_gains(model, act, card.array("kp") * draws["kp_scale"], card.array("kd") * draws["kd_scale"])
    data.qpos[0:3], data.qpos[3:7] = card.init_pos, (1.0, 0.0, 0.0, 0.0)
    data.qpos[qadr] = card.default_dof_angles
    mujoco.mj_forward(model, data)
    return model, data, qadr, dadr, act


def state_from_c(state, data):
    """``state`` with its env's physics set to the C state and the episode's sums at zero."""
    def one(x):
        return jnp.asarray(np.asarray(x), jnp.float32)[None]

    d = state.data.replace(qpos=one(data.qpos), qvel=one(data.qvel), qacc_warmstart=one(data.qacc_warmstart),
                           time=one(data.time))
    episode = {k: jnp.zeros_like(v) for k, v in state.episode.items()}
    episode["best_x"] = episode["x0"] = one(data.qpos[0])
    return state._replace(data=d, episode=episode)


def evaluator(env) -> WalkerBatch:
    """The sim-to-sim evaluator's env of the MJX env's robot, one slot: its course, command ranges and meter
    constants (the MJX env's). Only its course, gait clock, observation and meter are used, on the C states."""
    s, card = env.settings, env.card
    meter = MeterSettings(s.leg_distance_m, s.drivetrain_efficiency, s.idle_power_w, s.tilt_margin_rad,
                          card.fall_tilt_rad)
    batch = WalkerBatch(WalkerModel.build(card), env.course, meter, Stress(), EPISODE_S, 1, card.command_ranges)
    batch.start(0, 0, 0)
    return batch


def evaluator_state(batch: WalkerBatch, data: mujoco.MjData) -> np.ndarray:
    """The C data's pose and velocities as a full physics state of the evaluator's model (the same joints)."""
    scratch = mujoco.MjData(batch.walker.model)
    scratch.qpos[:], scratch.qvel[:] = data.qpos, data.qvel
    out = np.zeros(batch.walker.nstate)
    mujoco.mj_getState(batch.walker.model, scratch, out, mujoco.mjtState.mjSTATE_FULLPHYSICS)
    return out


#: robot -> whether its parity runs under the stress datapack. The G1 runs nominal: under the payload
#: and a low floor friction its steps part from MuJoCo C's by up to ~9e-3 rad of knee and ankle in one
#: control step even with the solver converged (measured; float32 against float64 where a foot
#: capsule's contact comes and goes), so the stress draws' parity (friction, payload, kp/kd) is the T1's.
PARITY_STRESS = {"g1_29dof": False, "t1_29dof": True}


@pytest.mark.parametrize("robot", sorted(TASKS))
def test_mjx_humanoid_steps_meter_and_observe_as_mujoco_c(robot: str) -> None:
    # the solver run to convergence: the catalog's 4 Newton iterations leave a step unconverged, and
    # MJX's and MuJoCo C's unconverged steps part (by up to ~0.08 rad of ankle angle in one control
    # step against the G1's stiff ankle tendon limits), which would hide what is compared. Under the
    # stress datapack (PARITY_STRESS): the episode's friction, payload and kp/kd draws are set on the
    # C side too (its first push comes after 5 s, past the steps compared: drawn, compiled, not applied).
    stress = PARITY_STRESS[robot]
    jitted = humanoid(robot, stress=stress, iterations=50, ls_iterations=50)
    env, card = jitted.env, jitted.env.card
    state = jitted.reset(jax.random.PRNGKey(0), 1)
    draws = {"friction": None, "payload_kg": 0.0, **{k: np.asarray(v)[0] for k, v in state.randomization.items()}}
    if stress:
        lo, hi = card.push_preset["push_interval_s"]
        assert 0.4 <= draws["friction"] <= 1.0 and 2.0 <= draws["payload_kg"] <= 5.0
        assert lo <= float(state.info["next_push_s"][0]) <= hi
        assert np.all((0.9 <= draws["kp_scale"]) & (draws["kp_scale"] <= 1.1)) and np.ptp(draws["kd_scale"]) > 0
    model, data, qadr, dadr, act = c_robot(env, draws)
    # the evaluator (the batched walker env) on the C states: the same joints, read in the card's order
    batch, slot = evaluator(env), np.array([0])
    assert (batch.nq, batch.nv) == (model.nq, model.nv) and np.array_equal(batch.walker.qpos_adr, qadr)
    assert np.array_equal(batch.walker.dof_adr, dadr)
    batch.state[0] = evaluator_state(batch, data)
    batch.observe(slot)  # the first control step's course command and gait clock, as the env's reset
    worst = {"qpos": 0.0, "energy_rel": 0.0, "obs": 0.0}
    steps = 30
    for t in range(steps):
        state = state_from_c(state, data)
        # +-0.3 (+-0.075 rad about the default pose): off the G1's stiff ankle tendon limits, where even
        # converged MJX and MuJoCo C part by ~1e-2 rad in a step (measured with +-0.6 under the payload)
        action = (0.3 * np.sin(0.3 * t + np.arange(card.num_dofs))).astype(np.float32)
        target = card.array("default_dof_angles") + card.action_scale * action.astype(np.float64)
        # the evaluator's sums from this step alone (the MJX episode's were zeroed from the C state)
        for name in ("steps", "units", "errors", "energy_wh", "risk_sum"):
            getattr(batch.sums, name)[0] = 0.0
        batch.sums.best_x[0] = data.qpos[0]
        states, frc = [], []
        data.ctrl[act] = target  # the PD targets: the actuators apply the law
        for _ in range(card.decimation):
            mujoco.mj_step(model, data)
            states.append(evaluator_state(batch, data))
            frc.append(data.qfrc_actuator[dadr].copy())
        # the evaluator's meter on the C physics steps (a fall's later steps unmetered)
        fell = bool(batch._meter(slot, np.stack(states)[None], np.stack(frc)[None])[0])
        sums = {name: float(getattr(batch.sums, name)[0]) for name in ("steps", "units", "energy_wh", "risk_sum")}
        state = jitted.step(state, jnp.asarray(action)[None])
        f = {k: float(np.asarray(v)[0]) for k, v in state.finished.items()}
        assert bool(f["fell"]) == fell, f"step {t}: fall differs"
        if fell:
            break
        qpos_j = np.asarray(state.data.qpos)[0]
        # the MJX step wrote the PD targets, not torques, into the actuators' ctrl
        np.testing.assert_allclose(np.asarray(state.data.ctrl)[0][act], target, rtol=1e-6, atol=1e-6)
        # stated tolerances (measured worst cases over the 30 steps, G1 nominal / T1 stressed: qpos
        # 6.2e-5 / 2.9e-5 rad or m, energy 1.8e-4 / 1.2e-4 relative, observation 6.6e-4 / 3.1e-4)
        np.testing.assert_allclose(qpos_j, data.qpos, atol=2e-3, err_msg=f"step {t}")
        assert sums["steps"] == card.decimation and sums["energy_wh"] > 0.0, t  # every physics step metered
        assert f["units_completed"] == pytest.approx(sums["units"], abs=2e-4), t
        assert f["energy_wh"] == pytest.approx(sums["energy_wh"], rel=2e-3), t
        assert f["risk_score"] == pytest.approx(sums["risk_sum"] / sums["steps"], abs=1e-3), t
        worst["qpos"] = max(worst["qpos"], float(np.max(np.abs(qpos_j - data.qpos))))
        worst["energy_rel"] = max(worst["energy_rel"], abs(f["energy_wh"] / sums["energy_wh"] - 1.0))
        # the next observation: the evaluator's course command, gait clock and observation on the C state
        batch.state[0], batch.last_action[0] = states[-1], action
        row = batch.observe(slot)[0]
        obs_j = np.asarray(state.obs)[0]
        np.testing.assert_allclose(obs_j, row, atol=5e-3, rtol=1e-3, err_msg=f"step {t}")
        worst["obs"] = max(worst["obs"], float(np.max(np.abs(obs_j - row))))
    assert t >= 10  # compared while the robot was up
    print(robot, worst)


def test_holosomas_shipped_g1_walker_walks_in_the_mjx_env() -> None:
    import onnxruntime as ort

    jitted = humanoid("g1_29dof")
    env = jitted.env
    st = env.settings
    meter = MeterSettings(st.leg_distance_m, st.drivetrain_efficiency, st.idle_power_w, st.tilt_margin_rad,
                          st.fall_tilt_rad)
    # the sim-to-sim evaluator on the same course, in this interpreter: seed 3, one episode, one process
    walker = WalkerEvaluation(policy="holosoma:g1_29dof/ppo", course=env.course, meter=meter,
                              stress=Stress(initial_joint_noise_rad=0.05), episode_s=EPISODE_S, seed=3)
    [reference], _ = evaluate(walker, 1, workers=1)
    assert reference["termination_reason"] == TerminationReason.MAX_STEPS
    assert reference["episode_length_s"] == pytest.approx(EPISODE_S, rel=1e-6)
    contract = resolve_contract(walker.policy)
    session = ort.InferenceSession(contract.onnx_path, providers=["CPUExecutionProvider"])
    name = session.get_inputs()[0].name
    state = jitted.reset(jax.random.PRNGKey(3), 1)
    for _ in range(env.max_episode_steps):
        action = session.run(None, {name: np.asarray(state.obs, np.float32)})[0]
        state = jitted.step(state, jnp.asarray(action))
        if float(state.done[0]) > 0:
            break
    row = env.finished_to_dicts(jax.device_get(state.finished))[0]
    assert row["termination_reason"] == TerminationReason.MAX_STEPS and row["errors"] == 0.0
    assert row["episode_length_s"] == pytest.approx(EPISODE_S, rel=1e-6)
    # both engines record the episode's time limit (a fall's J rate is over it)
    assert row["episode_limit_s"] == pytest.approx(reference["episode_limit_s"], rel=1e-6)
    assert reference["episode_limit_s"] == pytest.approx(EPISODE_S, rel=1e-6)
    speed, expected = row["achieved_speed_m_per_s"], reference["achieved_speed_m_per_s"]
    print(f"G1 PPO walker: MJX {speed:.3f} m/s, sim-to-sim {expected:.3f} m/s")
    assert expected > 0.3  # the walker walks in the evaluator ...
    assert abs(speed - expected) <= 0.15 * expected  # ... and as fast in the MJX env


def test_training_episodes_start_at_random_points_of_the_course() -> None:
    """``random_start``: the base placed along the course (in a dwell at a leg's end, or part-way along a leg),
    the course's state and the time spent so far set as :func:`locomotion.learning.course_point` says."""
    from econmotor.motor_backend.mjx.humanoid_env import HumanoidWalkerEnv
    from econmotor.motor_backend.mjx.wrappers import make_env

    env = make_env(HumanoidWalkerEnv, "humanoid_locomotion_g1", random_start=True)
    state = jax.jit(env.reset, static_argnums=1)(jax.random.PRNGKey(3), 64)
    x = np.asarray(state.data.qpos[:, 0])
    leg, dwell, done = (np.asarray(state.info[k]) for k in ("leg", "dwell_left_s", "legs_done"))
    steps = np.asarray(state.episode["control_steps"])
    course = env.course
    assert set(leg.astype(int)) == set(range(course.legs))
    assert (dwell > 0).any() and (dwell == 0).any()
    np.testing.assert_allclose(x[dwell > 0], (leg[dwell > 0] + 1) * course.leg_m, rtol=1e-6)
    walking = dwell == 0
    assert ((x[walking] >= leg[walking] * course.leg_m) & (x[walking] < (leg[walking] + 1) * course.leg_m)).all()
    np.testing.assert_array_equal(done, np.where(dwell > 0, leg + 1, leg))
    np.testing.assert_allclose(np.asarray(state.episode["best_x"]), x)  # the meter counts from where it stands
    assert (steps > 0).mean() > 0.9 and steps.max() < env.max_episode_steps
    limit = np.asarray(env.extra_metrics(state)["episode_limit_s"])  # the time limit from each start point
    np.testing.assert_allclose(limit, (env.max_episode_steps - steps) * env.control_dt_s, rtol=1e-6)
    fixed = jax.jit(make_env(HumanoidWalkerEnv, "humanoid_locomotion_g1").reset, static_argnums=1)(
        jax.random.PRNGKey(3), 4)
    assert np.all(np.asarray(fixed.episode["control_steps"]) == 0)  # evaluation starts at the course's start
