"""Sim-to-sim evaluation throughput, measured side by side in one run (runs in .venv-holosoma).

Two arms on the same compiled MuJoCo model of the policy's robot, the same seeded episode:

- **evaluation**: :func:`econmotor.motor_backend.holosoma.sim2sim.run_episode` as the backend's
  ``sim2sim`` job runs it: course controller, holosoma_inference's observation, the ONNX policy at
  its control rate, PD at the physics rate, the shared courier meter every physics step;
- **raw**: ``mj_step`` alone, replaying the actuator commands the evaluation arm applied (recorded
  once beforehand, untimed), so both arms simulate the same walk and the ratio is the cost of the
  policy, the observation, PD and metering.

Blocks run A B B A per round and the median of the rounds' ratios is printed with the range.
Simulated seconds per wall second (x real time) of each arm and ``evaluation / raw``:

    OMP_NUM_THREADS=1 .venv-holosoma/bin/python benchmarks/sim2sim_throughput.py
    OMP_NUM_THREADS=1 .venv-holosoma/bin/python benchmarks/sim2sim_throughput.py --policy holosoma:t1_29dof/ppo
"""

from __future__ import annotations

import argparse
import os
import statistics
import time

os.environ.setdefault("OMP_NUM_THREADS", "1")

#: the smallest run (tests/integration/test_benchmarks.py): one round of 0.2 simulated seconds
SMOKE_ARGS: list[str] = ["--episode-s", "0.2", "--rounds", "1"]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--policy", default="holosoma:g1_29dof/ppo")
    parser.add_argument("--episode-s", type=float, default=20.0, help="simulated seconds per block")
    parser.add_argument("--rounds", type=int, default=3)
    args = parser.parse_args()

    import mujoco
    import numpy as np

    from econmotor.motor_backend.holosoma import sim2sim as s
    from econmotor.couriers.policy_import import resolve_contract

    contract = resolve_contract(args.policy)
    robot = s.build_robot(contract)
    policy = s.onnx_policy(contract)
    course = s.CourseSettings(leg_m=10.0, dwell_s=20.0, speed_m_per_s=1.0)
    meter = s.MeterSettings(leg_distance_m=10.0, drivetrain_efficiency=0.8, idle_power_w=50.0, tilt_margin_rad=0.2,
                            fall_tilt_rad=0.8)
    stress = s.Stress()
    seed = 0

    # the evaluation arm's actuator commands, recorded once (untimed) for the raw arm to replay
    controls: list[np.ndarray] = []
    real_step = mujoco.mj_step

    def recording_step(m, d):
        controls.append(d.ctrl.copy())
        real_step(m, d)

    mujoco.mj_step = recording_step
    try:
        episode = s.run_episode(robot, contract, policy, course, meter, stress, args.episode_s, seed)
    finally:
        mujoco.mj_step = real_step
    sim_s = len(controls) * contract.physics_dt_s

    def evaluation_arm() -> float:
        start = time.perf_counter()
        s.run_episode(robot, contract, policy, course, meter, stress, args.episode_s, seed)
        return time.perf_counter() - start

    def raw_arm() -> float:
        m, d = robot.model, robot.data
        s.reset_robot(robot, contract, stress, np.random.default_rng(seed))
        start = time.perf_counter()
        for ctrl in controls:
            d.ctrl[:] = ctrl
            mujoco.mj_step(m, d)
        return time.perf_counter() - start

    ratios, evals, raws = [], [], []
    for _ in range(args.rounds):
        a1, b1, b2, a2 = evaluation_arm(), raw_arm(), raw_arm(), evaluation_arm()
        e, r = (a1 + a2) / 2, (b1 + b2) / 2
        evals.append(sim_s / e)
        raws.append(sim_s / r)
        ratios.append(r / e)
    print(f"policy {args.policy}: {sim_s:g} simulated s per block ({len(controls)} physics steps at "
          f"{1 / contract.physics_dt_s:g} Hz, policy at {contract.control_rate_hz:g} Hz), {args.rounds} rounds, "
          f"fell: {bool(episode['errors'])}")
    print(f"evaluation: {statistics.median(evals):.1f} x real time (simulated s per wall s; "
          f"range {min(evals):.1f}-{max(evals):.1f})")
    print(f"raw mj_step loop: {statistics.median(raws):.1f} x real time (range {min(raws):.1f}-{max(raws):.1f})")
    print(f"evaluation / raw: {statistics.median(ratios):.3f} (range {min(ratios):.3f}-{max(ratios):.3f}); "
          "the rest is the policy, observation, PD and metering")


if __name__ == "__main__":
    main()
