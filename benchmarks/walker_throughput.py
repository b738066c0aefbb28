"""The G1 on a CPU: the batched walker env against raw MuJoCo stepping, side by side in one run.

Every arm drives the same robot (the policy's card, as Holosoma's simulator models it) for the same
seeded episodes (nominal conditions, ``--episode-s`` each on a course without an end), and is reported
as control steps per wall second (50 Hz policy steps; 4 physics steps each) and x real time:

- **raw_1 / raw_2**: ``mj_step`` alone on one core / on both (one process each), replaying the PD
  targets the env's episodes applied (recorded once, untimed), PD in the actuators: the floor;
- **one_robot**: the evaluator the env replaced: one robot per process, the PD law, the clip and the
  shared meter in Python at every physics step, the ONNX policy one row at a time (one core);
- **env_1**: the batched env (:mod:`econmotor.locomotion.evaluation`) in this process, ``--slots`` robots;
- **env_processes**: two worker processes of ``--slots`` robots each (the evaluator's default), with
  their start-up (spawn, imports, the model, the ONNX session) timed apart as ``startup_s``;
- **train_1 / train_2**: the CPU trainer's PPO iterations (:mod:`econmotor.motor_backend.mujoco.walker_training`,
  the task catalog's recipe, reward and gain, ``--train-envs`` robots from the policy's actor, random starts on
  the same course): its robots stepped in its own process (``collect_workers: 1``) / in two collect workers
  (``collect_workers: 2``, :mod:`econmotor.motor_backend.mujoco.walker_collect`), the update in the trainer's
  process; env steps per wall second over ``--train-iterations`` iterations after a first one (the workers'
  start-up) untimed, the update included (``collect_1`` / ``collect_2``: collection alone; under
  ``policy_lag: 1`` the wait for the workers after the update);
  ``train_2_update_1``: ``train_2`` with its update on one torch thread (the trainer's default runs it on
  every usable CPU, the workers' cores idle while they wait for the next actor).

Printed last: the trainer's ``train_2 / raw_2`` (the share of the machine's MuJoCo speed a training run
gets on both cores; the goal is at least 0.5), then ``env_processes / raw_2``, the share a price gets.
``--trainer-only`` measures the raw floors and the trainer's arms alone; ``--hyperparameters KEY=VALUE``
(repeatable) sets a recipe setting of every trainer arm over the catalog's. On idle cores:

    OMP_NUM_THREADS=1 .venv/bin/python benchmarks/walker_throughput.py
    OMP_NUM_THREADS=1 .venv/bin/python benchmarks/walker_throughput.py --trainer-only
    OMP_NUM_THREADS=1 .venv/bin/python benchmarks/walker_throughput.py --policy holosoma:t1_29dof/ppo
    OMP_NUM_THREADS=1 .venv/bin/python benchmarks/walker_throughput.py --trainer-only --hyperparameters policy_lag=1
"""

from __future__ import annotations

import argparse
import multiprocessing as mp
import os
import time

os.environ.setdefault("OMP_NUM_THREADS", "1")

#: the smallest run (tests/integration/test_benchmarks.py)
SMOKE_ARGS: list[str] = ["--episode-s", "0.4", "--episodes", "4", "--slots", "2", "--train-envs", "4",
                          "--train-steps", "8", "--train-iterations", "1"]


def _evaluation(policy: str, episode_s: float, slots: int):
    from econmotor.locomotion.course import CourseSettings
    from econmotor.locomotion.evaluation import WalkerEvaluation
    from econmotor.locomotion.stress import Stress
    from econmotor.locomotion.task import MeterSettings

    return WalkerEvaluation(policy=policy, course=CourseSettings(leg_m=10.0, dwell_s=20.0, speed_m_per_s=1.0, legs=0),
                            meter=MeterSettings(10.0, 0.8, 50.0, 0.2, 0.8),
                            stress=Stress(initial_joint_noise_rad=0.05), episode_s=episode_s, seed=0, slots=slots)


def record_targets(ev, episodes: int):
    """The PD targets each episode applied, per control step (untimed), and the start states."""
    import numpy as np

    from econmotor.locomotion.env import run_episodes
    from econmotor.locomotion.evaluation import build_batch

    batch, policy = build_batch(ev, slots=1)
    targets, starts = [], []
    original = batch._rollout

    def recording(slots, tgt):
        targets[-1].append(tgt[0].copy())
        return original(slots, tgt)

    batch._rollout = recording
    for i in range(episodes):
        batch.start(0, i, ev.seed + i)
        starts.append(batch.state[0].copy())
        targets.append([])
        batch.episodes[0] = None
        run_episodes(batch, policy, [(i, ev.seed + i)])
    return starts, [np.asarray(t) for t in targets]


def replay(ev, starts, targets) -> float:
    """raw: mj_step over the recorded targets, one robot after another; returns wall seconds."""
    import mujoco

    from econmotor.couriers.policy_import import resolve_contract
    from econmotor.locomotion.model import WalkerModel

    contract = resolve_contract(ev.policy)
    walker = WalkerModel.build(contract.card, contract.kp, contract.kd)
    m, d = walker.model, mujoco.MjData(walker.model)
    t0 = time.perf_counter()
    for state, episode in zip(starts, targets, strict=True):
        mujoco.mj_setState(m, d, state, mujoco.mjtState.mjSTATE_FULLPHYSICS)
        for target in episode:
            d.ctrl[walker.actuators] = target
            mujoco.mj_step(m, d, nstep=contract.card.decimation)
    return time.perf_counter() - t0


def _replay_worker(args) -> float:
    return replay(*args)


def one_robot(ev, episodes: int) -> float:
    """The replaced evaluator's loop: Python PD, clip and meter at every physics step, batch-1 policy."""
    import mujoco
    import numpy as np

    from econmotor.couriers.physics import root_tilt_rad
    from econmotor.couriers.policy_import import batched_onnx_policy, resolve_contract
    from econmotor.economics import courier_formulas as cf
    from econmotor.locomotion import course as crs
    from econmotor.robots import observation as obs
    from econmotor.robots.model import joint_indices, model_spec

    c = resolve_contract(ev.policy)
    card, policy = c.card, batched_onnx_policy(c)
    m = model_spec(card).compile()
    d = mujoco.MjData(m)
    qadr, dadr, act = joint_indices(m, card)
    kp, kd, limit, default = np.asarray(c.kp), np.asarray(c.kd), card.array("effort_limits"), card.array(
        "default_dof_angles")
    mt = ev.meter
    constants = cf.MeterConstants(mt.leg_distance_m, mt.drivetrain_efficiency, mt.idle_power_w, card.physics_dt_s,
                                  mt.tilt_margin_rad, mt.fall_tilt_rad)
    t0 = time.perf_counter()
    for i in range(episodes):
        rng = np.random.default_rng(ev.seed + i)
        mujoco.mj_resetData(m, d)
        d.qpos[0:3], d.qpos[3:7] = card.init_pos, (1, 0, 0, 0)
        d.qpos[qadr] = default + rng.uniform(-0.05, 0.05, card.num_dofs)
        mujoco.mj_forward(m, d)
        state, phase, standing = crs.course_start(np), obs.initial_phase(np), False
        last, sums = np.zeros(card.num_dofs, np.float32), cf.MeterSums(best_x=float(d.qpos[0]))
        for _ in range(round(ev.episode_s / card.control_dt_s)):
            state, vx, yaw = crs.course_command(state, d.qpos[0], d.qpos[1], crs.heading_yaw(d.qpos[3:7], np),
                                                ev.course, card.control_dt_s, 1.0, (-1.0, 1.0), np)
            lin = np.array([float(vx), 0.0])
            phase, standing = obs.advance_phase(phase, standing, lin, yaw, card, np)
            row = obs.build_observation(card, np, quat_wxyz=d.qpos[3:7], ang_vel_body=d.qvel[3:6], q=d.qpos[qadr],
                                        qd=d.qvel[dadr], lin_vel_cmd=lin, ang_vel_cmd=yaw, last_action=last,
                                        phase=phase)
            last = np.clip(policy(np.stack([row, row]))[0], -card.action_clip, card.action_clip)
            target = default + card.action_scale * last.astype(np.float64)
            for _ in range(card.decimation):
                d.ctrl[act] = np.minimum(np.maximum(kp * (target - d.qpos[qadr]) - kd * d.qvel[dadr], -limit), limit)
                mujoco.mj_step(m, d)
                tilt = root_tilt_rad(d.qpos[:7].tolist(), True, cf.PY)
                reading = cf.StepReading(float(d.qpos[0]), cf.mechanical_power_w(
                    d.qfrc_actuator[dadr].tolist(), d.qvel[dadr].tolist(), cf.PY), tilt, tilt > card.fall_tilt_rad)
                cf.meter_step(sums, reading, constants, cf.PY)
    return time.perf_counter() - t0


def train_rate(ev, workers: int, num_envs: int | None, steps: int, iterations: int,
               update_threads: int | None = None, overrides: dict[str, str] | None = None) -> tuple[float, float]:
    """(env steps per wall second, of collection alone) of the trainer's iterations with ``workers`` collect
    workers (after a first iteration, untimed: the workers' start-up); ``update_threads``: the update's torch
    threads (None: the trainer's default)."""
    import numpy as np

    from econmotor.config.objective_profile import ObjectiveVector
    from econmotor.couriers.onnx_actor import policy_file, read_actor
    from econmotor.couriers.policy_import import resolve_contract
    from econmotor.locomotion.conditions import WalkerSetup
    from econmotor.motor_backend.mujoco.walker_backend import walker_train_settings
    from econmotor.motor_backend.mujoco.walker_recipe import WalkerPPOConfig
    from econmotor.motor_backend.mujoco.walker_training import WalkerLearner, WalkerTrainingRun
    from econmotor.objectives.loader import objective_from_vector
    from econmotor.tasks import get_task

    c = resolve_contract(ev.policy)
    task = "humanoid_locomotion_g1" if c.card.name.startswith("g1") else "humanoid_locomotion_t1"
    spec = get_task(task)
    trainer = walker_train_settings(spec)
    recipe = {**trainer.ppo, **(overrides or {})}
    num_envs = int(num_envs or recipe.get("num_envs", 32))
    recipe.update(num_envs=num_envs, steps_per_iteration=steps)
    if (num_envs * steps) % int(recipe.get("num_minibatches", 1)):
        recipe["num_minibatches"] = 1
    setup = WalkerSetup(contract=c, card=c.card, course=ev.course, meter=ev.meter, stress=ev.stress,
                        episode_s=ev.episode_s, notes=(), datapack_ids=())
    run = WalkerTrainingRun(
        run_dir=None, setup=setup, cfg=WalkerPPOConfig.from_mapping(recipe),  # type: ignore[arg-type]
        objective=objective_from_vector(ObjectiveVector.from_preset("energy_saver"), "energy_saver"),
        economics=spec.economics, gain=trainer.econ_gain, weights=trainer.weights, params=trainer.params, seed=0,
        max_steps=10**12, init=read_actor(policy_file(ev.policy), ev.policy), kp=np.asarray(c.kp),
        kd=np.asarray(c.kd), command_ranges=c.command_ranges, collect_workers=workers,
        update_threads=update_threads)
    learner = WalkerLearner(run)
    try:
        learner.learn(learner.env_steps + 1)  # one iteration: the workers' start-up
        t0, collect_s = time.perf_counter(), 0.0
        for _ in range(iterations):
            collect_s += learner.learn(learner.env_steps + 1)["collect_s"]
        wall = time.perf_counter() - t0
    finally:
        learner.close()
    env_steps = iterations * num_envs * steps
    return env_steps / wall, env_steps / collect_s


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--policy", default="holosoma:g1_29dof/ppo")
    parser.add_argument("--episode-s", type=float, default=20.0, help="simulated seconds per episode")
    parser.add_argument("--episodes", type=int, default=16)
    parser.add_argument("--slots", type=int, default=8, help="robots per process")
    parser.add_argument("--train-envs", type=int, default=None,
                        help="the trainer's robots (default: the catalog's recipe's, 64 on the G1, 32 on the T1)")
    parser.add_argument("--train-steps", type=int, default=128,
                        help="the trainer's control steps per iteration (the catalog's: 128)")
    parser.add_argument("--train-iterations", type=int, default=4, help="timed trainer iterations per arm")
    parser.add_argument("--hyperparameters", action="append", default=[], metavar="KEY=VALUE",
                        help="a recipe setting for every trainer arm, over the catalog's (repeatable)")
    parser.add_argument("--trainer-only", action="store_true",
                        help="the raw floors and the trainer's arms only (no evaluator arms)")
    args = parser.parse_args()
    overrides = dict(kv.split("=", 1) for kv in args.hyperparameters)

    from econmotor.locomotion.evaluation import evaluate

    ev = _evaluation(args.policy, args.episode_s, args.slots)
    starts, targets = record_targets(ev, args.episodes)
    control_steps = sum(len(t) for t in targets)
    sim_s = control_steps * 0.02
    rates: dict[str, float] = {}
    rates["raw_1"] = control_steps / replay(ev, starts, targets)
    half = len(starts) // 2
    with mp.get_context("spawn").Pool(2) as pool:
        pool.map(_replay_worker, [(ev, starts[:1], [targets[0][:5]])] * 2)  # warm both workers
        t0 = time.perf_counter()
        pool.map(_replay_worker, [(ev, starts[:half], targets[:half]), (ev, starts[half:], targets[half:])])
        rates["raw_2"] = control_steps / (time.perf_counter() - t0)
    if not args.trainer_only:
        rates["one_robot"] = (control_steps / one_robot(ev, min(args.episodes, 4)) * min(args.episodes, 4)
                              / args.episodes)
        t0 = time.perf_counter()
        evaluate(ev, args.episodes, workers=1)
        rates["env_1"] = control_steps / (time.perf_counter() - t0)
        tiny = _evaluation(args.policy, 0.02, args.slots)
        t0 = time.perf_counter()
        evaluate(tiny, 2, workers=2)
        startup_s = time.perf_counter() - t0
        t0 = time.perf_counter()
        evaluate(ev, args.episodes, workers=2)
        wall = time.perf_counter() - t0
        rates["env_processes"] = control_steps / max(wall - startup_s, 1e-9)
    for workers in (1, 2):
        rates[f"train_{workers}"], rates[f"collect_{workers}"] = train_rate(
            ev, workers, args.train_envs, args.train_steps, args.train_iterations, overrides=overrides)
    # the same two-worker trainer with its update on one torch thread (one core idle while the workers wait)
    rates["train_2_update_1"], _ = train_rate(ev, 2, args.train_envs, args.train_steps, args.train_iterations, 1,
                                              overrides)
    print(f"policy {args.policy}: {args.episodes} episodes x {args.episode_s:g} s = {sim_s:g} simulated s, "
          f"{control_steps} control steps; {args.slots} robots per process; cores: {os.cpu_count()}; trainer: "
          f"{args.train_envs or 'the recipe'} robots x {args.train_steps} steps per iteration, "
          f"{args.train_iterations} timed"
          + (f"; recipe {overrides}" if overrides else ""))
    for name, rate in rates.items():
        print(f"{name:>14}: {rate:8.0f} control steps/s  {rate * 0.02:6.1f} x real time")
    ratio = {name: rates[name] / rates["raw_1" if name.endswith("_1") or name == "one_robot" else "raw_2"]
             for name in rates}
    print(f"train_1 / raw_1: {ratio['train_1']:.3f}; collect_1 / raw_1: {ratio['collect_1']:.3f}; "
          f"collect_2 / raw_2: {ratio['collect_2']:.3f}; train_2 / train_1: {rates['train_2'] / rates['train_1']:.3f}")
    print(f"train_2 / train_2_update_1 (the update on every core / on one): "
          f"{rates['train_2'] / rates['train_2_update_1']:.3f}")
    print(f"train_2 / raw_2: {ratio['train_2']:.3f}")
    if not args.trainer_only:
        print(f"env_processes start-up: {startup_s:.2f} s (spawn, imports, model, ONNX session); "
              f"wall with it {wall:.2f} s")
        print(f"env_1 / raw_1: {ratio['env_1']:.3f}; one_robot / raw_1: {ratio['one_robot']:.3f}")
        print(f"env_processes / raw_2: {ratio['env_processes']:.3f}")


if __name__ == "__main__":
    main()
