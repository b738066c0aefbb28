"""The batched MuJoCo walker env (locomotion/env.py) on the real G1 and T1, in the main interpreter.

- PD by MuJoCo's actuators equals the PD law computed in Python before each physics step (the one-robot
  evaluator's inner loop), over a fixed action sequence: joint positions, and the electrical energy the
  old meter read from ``qfrc_actuator`` and ``qvel`` against the env's from its actuator-force sensors;
- an episode's figures depend on its seed only: one slot or several, one worker process or two, under a
  stress datapack with every per-episode draw (friction, payload, pushes, gains, control delay);
- the shipped PPO walkers walk the task's course at the speed the one-robot evaluator measured (seeds 0-3
  there: G1 0.5282 m/s, T1 0.5744 m/s) and at today's energy with the cards' motor models (G1 2.2706 Wh per
  leg, T1 2.5925; 0.9987 and 1.1811 on the meter without the windings' heat);
- standing still under the dwell draws the windings' heat above the idle draw;
- the runaway rule ends a blown-up episode as a fall.
"""

from __future__ import annotations

import numpy as np
import pytest

from econmotor.couriers.policy_import import resolve_contract
from econmotor.economics import courier_formulas as cf
from econmotor.locomotion.course import CourseSettings
from econmotor.locomotion.env import WalkerBatch, run_episodes
from econmotor.locomotion.evaluation import WalkerEvaluation, build_batch, evaluate
from econmotor.locomotion.model import WalkerModel
from econmotor.locomotion.stress import Stress
from econmotor.locomotion.task import MeterSettings, course_settings, meter_settings, walker_settings
from econmotor.robots.model import joint_indices, model_spec
from econmotor.tasks.catalog import load_catalog

METER = MeterSettings(leg_distance_m=2.0, drivetrain_efficiency=0.8, idle_power_w=50.0, tilt_margin_rad=0.2,
                      fall_tilt_rad=0.8)
SHORT = CourseSettings(leg_m=2.0, dwell_s=1.0, speed_m_per_s=0.8, legs=2)
EVERY_DRAW = Stress(friction_range=(0.4, 1.0), payload_kg_range=(2.0, 5.0), push_interval_s=(1.0, 2.0),
                    max_push_vel_m_per_s=(0.5, 0.5), initial_joint_noise_rad=0.05, kp_range=(0.9, 1.1),
                    kd_range=(0.9, 1.1), ctrl_delay_steps=(0, 1))


@pytest.fixture(scope="module")
def g1_ppo():
    return resolve_contract("holosoma:g1_29dof/ppo")


def python_pd_reference(card, kp, kd, actions):
    """The one-robot evaluator's loop: the card's own model (motor actuators), the PD torque computed in
    Python before every physics step, energy metered from ``qfrc_actuator`` and ``qvel`` after it."""
    import mujoco

    model = model_spec(card).compile()
    data = mujoco.MjData(model)
    qadr, dadr, act = joint_indices(model, card)
    data.qpos[0:3], data.qpos[3:7] = card.init_pos, (1.0, 0.0, 0.0, 0.0)
    data.qpos[qadr] = card.array("default_dof_angles")
    mujoco.mj_forward(model, data)
    limit, default = card.array("effort_limits"), card.array("default_dof_angles")
    mech_j, heat_j, qpos = 0.0, 0.0, []
    for action in actions:
        target = default + card.action_scale * action.astype(np.float64)
        for _ in range(card.decimation):
            q, qd = data.qpos[qadr], data.qvel[dadr]
            data.ctrl[act] = np.clip(kp * (target - q) - kd * qd, -limit, limit)
            mujoco.mj_step(model, data)
            mech_j += float(np.sum(np.abs(data.qfrc_actuator[dadr] * data.qvel[dadr]))) * card.physics_dt_s
            heat_j += float(np.sum(card.heat_coeff() * data.qfrc_actuator[dadr] ** 2)) * card.physics_dt_s
        qpos.append(data.qpos[qadr].copy())
    return np.asarray(qpos), mech_j, heat_j


def test_pd_by_actuators_equals_the_python_pd_law(g1_ppo):
    card, kp, kd = g1_ppo.card, np.asarray(g1_ppo.kp), np.asarray(g1_ppo.kd)
    steps = 50  # one second of control
    phase = np.arange(card.num_dofs) * 0.7
    actions = [np.float32(0.4) * np.sin(0.3 * k + phase).astype(np.float32) for k in range(steps)]
    ref_qpos, ref_mech_j, ref_heat_j = python_pd_reference(card, kp, kd, actions)
    batch = WalkerBatch(WalkerModel.build(card, kp, kd), SHORT, METER, Stress(), 60.0, 1, g1_ppo.command_ranges)
    batch.start(0, 0, 0)
    slots, qpos = np.array([0]), []
    for action in actions:
        batch.act(slots, action[None, :])
        qpos.append(batch._qpos(batch.state[0])[batch.walker.qpos_adr].copy())
    assert np.max(np.abs(np.asarray(qpos) - ref_qpos)) < 2e-3  # rad, after 200 physics steps
    length_s = steps * card.control_dt_s
    ref_wh = cf.electrical_energy_wh(ref_mech_j / length_s, METER.drivetrain_efficiency, METER.idle_power_w, length_s,
                                     ref_heat_j / length_s)
    assert float(batch.sums.energy_wh[0]) == pytest.approx(ref_wh, rel=5e-3)
    assert float(batch.heat_wh[0]) == pytest.approx(ref_heat_j / 3600.0, rel=5e-3)
    assert ref_mech_j > 1.0 and ref_heat_j > 1.0  # the sequence does work and heats: the check compares something


def figures(episodes):
    return [(e["errors"], e["units_completed"], e["energy_wh"], e["stress_payload_kg"]) for e in episodes]


def test_an_episode_depends_on_its_seed_only(g1_ppo):
    ev = WalkerEvaluation(policy=g1_ppo.onnx_path, course=SHORT, meter=METER, stress=EVERY_DRAW, episode_s=12.0,
                          seed=40)
    alone = []
    for i in range(4):  # one slot, one episode at a time
        batch, policy = build_batch(ev, g1_ppo, slots=1)
        run_episodes(batch, policy, [(i, ev.seed + i)], lambda _i, ep: alone.append(ep))
    together, _ = evaluate(WalkerEvaluation(**{**ev.__dict__, "slots": 4}), 4, workers=1)
    two_workers, _ = evaluate(WalkerEvaluation(**{**ev.__dict__, "slots": 2}), 4, workers=2)
    assert len({e["stress_payload_kg"] for e in alone}) == 4  # the seeds drew different conditions
    for a, b in ((alone, together), (alone, two_workers)):
        for x, y in zip(figures(a), figures(b), strict=True):
            assert x[0] == y[0] and x[3] == y[3]
            assert x[1] == pytest.approx(y[1], rel=1e-3) and x[2] == pytest.approx(y[2], rel=1e-3)


@pytest.mark.parametrize(("policy", "task_id", "speed", "wh_per_leg"), [
    ("holosoma:g1_29dof/ppo", "humanoid_locomotion_g1", 0.5282, 2.2706),
    ("holosoma:t1_29dof/ppo", "humanoid_locomotion_t1", 0.5744, 2.5925),
])
def test_the_shipped_walkers_walk_at_todays_nominal_speed_and_energy(policy, task_id, speed, wh_per_leg):
    spec = load_catalog().get(task_id)
    settings = walker_settings(spec)
    ev = WalkerEvaluation(policy=policy, course=course_settings(settings),
                          meter=MeterSettings(**meter_settings(task_id, settings, spec.source)),
                          stress=Stress(initial_joint_noise_rad=float(settings["sim2sim_start_joint_noise_rad"])),
                          episode_s=float(settings["sim2sim_episode_s"]), seed=0, slots=2)
    episodes, _ = evaluate(ev, 2)
    legs = sum(e["units_completed"] for e in episodes)
    assert sum(e["errors"] for e in episodes) == 0 and legs > 5.9
    assert np.mean([e["achieved_speed_m_per_s"] for e in episodes]) == pytest.approx(speed, rel=0.03)
    assert sum(e["energy_wh"] for e in episodes) / legs == pytest.approx(wh_per_leg, rel=0.03)
    # a plausible amount of work for the walk: mechanical cost of transport P_mech / (m g v) in 0.2-1.5
    # (metering a force that is not the actuators', such as gravity's qfrc_bias, gives about 0.1)

    mass = float(np.sum(WalkerModel.build(resolve_contract(policy).card).model.body_mass))
    cot = [e["mean_mech_power_w"] * e["episode_length_s"] / (mass * 9.81 * e["distance_m"]) for e in episodes]
    assert all(0.2 < c < 1.5 for c in cot), cot


def test_the_runaway_rule_ends_a_blown_up_episode_as_a_fall(g1_ppo):
    ev = WalkerEvaluation(policy=g1_ppo.onnx_path, course=SHORT, meter=METER, stress=Stress(), episode_s=10.0, seed=0)
    batch, policy = build_batch(ev, g1_ppo, slots=1)
    batch.runaway = 0.3  # m/s: a walker commanded 0.8 m/s passes it while upright
    ended = []
    run_episodes(batch, policy, [(0, 0)], lambda _i, ep: ended.append(ep))
    [episode] = ended
    assert episode["termination_reason"] == "fall" and episode["errors"] == 1.0
    assert episode["episode_length_s"] < 5.0
    assert episode["risk_score"] < 0.05  # upright all the while: only the runaway rule could end it


@pytest.mark.parametrize("workers", [1, 2])
def test_a_stopped_evaluation_returns_the_episodes_up_to_the_look_that_stopped_it(g1_ppo, workers):
    """``stop`` is asked at every ``batch`` boundary in order, even when several episodes end in one
    control step, and the evaluation returns exactly the episodes it was asked about when it said stop:
    what a report derives from them (speed, power) does not depend on how many were still in flight."""
    ev = WalkerEvaluation(policy=g1_ppo.onnx_path, course=SHORT, meter=METER, stress=Stress(), episode_s=0.4,
                          seed=3, slots=6)
    asked: list[int] = []

    def stop(rows):
        asked.append(len(rows))
        return len(rows) >= 2

    episodes, _ = evaluate(ev, 12, workers, stop=stop, batch=2)
    assert asked == [2] and len(episodes) == 2  # six end together at their time limit: the look at 2 still decides


def test_standing_under_the_dwell_draws_the_windings_heat_above_the_idle_draw(g1_ppo):
    """The G1 standing still under its shipped walker (a 0 m/s command, as in the course's dwells): holding
    its bent knees is current, and the meter charges the windings' heat on top of the idle draw (without
    the card's motor model the same stand costs little more than idle)."""
    import dataclasses

    from econmotor.locomotion.evaluation import batched_onnx_policy

    spec = load_catalog().get("humanoid_locomotion_g1")
    settings = walker_settings(spec)
    meter = MeterSettings(**meter_settings(spec.task_id, settings, spec.source))
    stand = CourseSettings(leg_m=10.0, dwell_s=20.0, speed_m_per_s=0.0, legs=1)

    def power(card) -> tuple[float, float]:
        batch = WalkerBatch(WalkerModel.build(card, np.asarray(g1_ppo.kp), np.asarray(g1_ppo.kd)), stand, meter,
                            Stress(), 4.0, 2, g1_ppo.command_ranges)
        rows: list[dict] = []
        run_episodes(batch, batched_onnx_policy(g1_ppo), [(0, 0), (1, 1)], lambda i, ep: rows.append(ep))
        assert sum(r["errors"] for r in rows) == 0 and all(r["distance_m"] < 0.5 for r in rows)  # it stood
        return float(np.mean([r["mean_power_w"] for r in rows])), float(np.mean([r["mean_heat_power_w"] for r in rows]))

    standing_w, heat_w = power(g1_ppo.card)
    bare_w, bare_heat_w = power(dataclasses.replace(g1_ppo.card, motor_model=None))
    print(f"G1 standing under its walker: {standing_w:.1f} W ({heat_w:.1f} W winding heat, idle "
          f"{meter.idle_power_w:g} W); without the motor model {bare_w:.1f} W")
    assert bare_heat_w == 0.0 and heat_w > 100.0
    assert standing_w > meter.idle_power_w + 100.0
    assert standing_w - bare_w == pytest.approx(heat_w, rel=1e-6)  # the same stand: only the heat differs
