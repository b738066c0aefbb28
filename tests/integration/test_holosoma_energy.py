"""The sim-to-sim meter's energy against a figure computed without it (in .venv-holosoma).

The meter reads MuJoCo's actuator forces (``qfrc_actuator``) and joint velocities each physics step. The
check here reads neither: it recomputes the torque the PD loop commands from the module's documented law
(``tau = clip(kp (default + action_scale * action - q) - kd qd, effort limits)``, with the actions the
policy returned and the state before each physics step) and multiplies it by how far each joint moved in
that step: the actuators' work from positions over time, ``sum |tau * dq|`` (the integrator advances
``q`` by ``dt * qvel``, so this is ``sum |tau qvel| dt``). Electrical energy is then
``(work / efficiency + idle power * time) / 3600`` Wh. A walking G1 must also do a plausible amount of work
for the distance it walks: a mechanical cost of transport ``P_mech / (m g v)`` between 0.2 and 1.5 (the
shipped policies measure 0.4-0.7; metering a force that is not the actuators', such as gravity's
``qfrc_bias``, gives about 0.1).
"""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import pytest

from econmotor.motor_backend.holosoma.backend import find_holosoma_python
from econmotor.motor_backend.holosoma.jobs import job_environment

pytestmark = [pytest.mark.holosoma]
REPO = Path(__file__).resolve().parents[2]

INDEPENDENT = r"""
import json, sys
import numpy as np
from econmotor.motor_backend.holosoma import sim2sim as s
from econmotor.couriers.policy_import import resolve_contract

out = {}
for name in sys.argv[1:]:
    c = resolve_contract(name)
    robot = s.build_robot(c)
    act = s.onnx_policy(c)
    targets, starts, record = [], [], []

    def policy(row):
        a = np.clip(np.asarray(act(row), dtype=np.float32).reshape(-1), -c.card.action_clip, c.card.action_clip)
        targets.append(np.asarray(c.card.default_dof_angles) + c.card.action_scale * a.astype(np.float64))
        return a

    def before_control_step(robot, builder, row, vx, yaw_rate):
        starts.append((len(record), robot.data.qpos[robot.qpos_adr].copy(), robot.data.qvel[robot.dof_adr].copy()))

    meter = s.MeterSettings(leg_distance_m=2.0, drivetrain_efficiency=0.8, idle_power_w=50.0, tilt_margin_rad=0.05,
                            fall_tilt_rad=0.8)
    ep = s.run_episode(robot, c, policy, s.CourseSettings(2.0, 1.0, 0.8), meter, s.Stress(initial_joint_noise_rad=0.05),
                       7.0, 5, record=record, on_observation=before_control_step)
    kp, kd, limit = np.asarray(c.kp), np.asarray(c.kd), np.asarray(c.card.effort_limits)
    ends = [start for start, _, _ in starts[1:]] + [len(record)]
    work_j = 0.0
    for (start, q, qd), end, target in zip(starts, ends, targets):
        for k in range(start, end):
            tau = np.clip(kp * (target - q) - kd * qd, -limit, limit)
            q_next = record[k]["qpos"][robot.qpos_adr]
            work_j += float(np.sum(np.abs(tau * (q_next - q))))
            q, qd = q_next, record[k]["qvel"]
    seconds = len(record) * c.physics_dt_s
    out[name] = {"episode": ep, "work_j": work_j, "seconds": seconds, "mass_kg": float(np.sum(robot.model.body_mass)),
                 "energy_wh": (work_j / meter.drivetrain_efficiency + meter.idle_power_w * seconds) / 3600.0}
print("@@energy " + json.dumps(out))
"""


@pytest.fixture(scope="module")
def measured() -> dict:
    python = find_holosoma_python(REPO / ".venv-holosoma")
    proc = subprocess.run([str(python), "-c", INDEPENDENT, "holosoma:g1_29dof/ppo", "holosoma:t1_29dof/fastsac"],
                          capture_output=True, text=True, env=job_environment(), timeout=300)
    line = next((ln for ln in proc.stdout.splitlines() if ln.startswith("@@energy ")), None)
    assert line is not None, proc.stdout[-2000:] + proc.stderr[-4000:]
    return json.loads(line[len("@@energy "):])


def test_metered_energy_equals_the_actuators_work_from_positions_over_time(measured: dict) -> None:
    for name, got in measured.items():
        ep = got["episode"]
        assert ep["termination_reason"] == "time_out" and got["seconds"] == pytest.approx(7.0), name
        assert ep["energy_wh"] == pytest.approx(got["energy_wh"], rel=1e-9), name
        assert ep["mean_mech_power_w"] == pytest.approx(got["work_j"] / got["seconds"], rel=1e-9), name


def test_a_walking_humanoid_does_a_plausible_amount_of_work_for_its_distance(measured: dict) -> None:
    for name, got in measured.items():
        ep = got["episode"]
        assert ep["distance_m"] > 2.0 and ep["walking_s"] > 4.0, name  # it walked
        speed = ep["distance_m"] / ep["walking_s"]
        cost_of_transport = ep["mean_mech_power_w"] / (got["mass_kg"] * 9.81 * speed)
        assert 0.2 < cost_of_transport < 1.5, (name, cost_of_transport)
