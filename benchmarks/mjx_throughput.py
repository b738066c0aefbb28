"""MJX throughput, measured side by side in one run.

1. Env steps/s of ``jit(step)`` (batched MJX couriers) with and without the economics inside
   the step (``env_step_throughput``; goal: ratio >= 0.98). "With": the batched
   ``GymCourierEnv`` as the backend trains on it (``wrappers.make_env``: metering, novelty table,
   overlay of the default objective vector);
   "without": the same env built with ``economics=False`` (physics, task reward, observation,
   auto-reset only). Each arm is one jitted ``lax.scan`` of ``--env-steps`` steps with random
   actions drawn inside it; blocks run in A B B A order per round (load drifting during a round
   hits both arms alike) and the median round ratio is printed with the range.
2. PPO training env steps/s of the ``mjx`` backend (JAX PPO, ``num_envs`` batched MJX envs on
   the JAX device) vs the ``mujoco`` backend's Stable-Baselines3 PPO (its catalog num_envs of
   in-process Gymnasium envs on the CPU), same task (hopper_courier), same objective
   (``ppo_vs_sb3``). Each is timed from its first to its last progress report after the first
   report, i.e. without env creation, XLA compilation (mjx: the first iteration) or
   evaluation (neither runs held-out evaluations: ``select_every_steps=0``). Goal on a GPU:
   ratio >= 100; on 2 CPU cores it is reported as it is.
3. With ``--physics`` only: env steps/s of the step with economics, the body stepped by MuJoCo C from the
   jitted step (``cpu_physics: mujoco``) against MJX, A B B A as 1 (``physics_throughput``).

    .venv/bin/python benchmarks/mjx_throughput.py                   # GPU: catalog num_envs
    .venv/bin/python benchmarks/mjx_throughput.py --mjx-envs 32 --mjx-steps 20000 --sb3-steps 8192 \
        --env-envs 8 --env-steps 20 --env-rounds 3                                           # CPU
    .venv/bin/python benchmarks/mjx_throughput.py --physics --env-steps 100 --env-rounds 3  # C against MJX
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time

os.environ.setdefault("OMP_NUM_THREADS", "1")
# single-threaded Eigen inside XLA's CPU kernels (measured 172 vs 137 hopper env steps/s, 8 envs, 2 cores)
os.environ.setdefault("XLA_FLAGS", "--xla_cpu_multi_thread_eigen=false intra_op_parallelism_threads=1")

TASK = "hopper_courier"
#: the smallest run (tests/integration/test_benchmarks.py): 1 env everywhere, one SB3 PPO rollout (4 x 512 steps)
SMOKE_ARGS: list[str] = ["--env-envs", "1", "--env-steps", "1", "--env-rounds", "1", "--mjx-envs", "1",
                         "--mjx-steps", "60", "--sb3-steps", "2048"]


def env_step_throughput(task_id: str = TASK, num_envs: int = 0, steps_per_block: int = 0, rounds: int = 5,
                        seed: int = 0, print_fn=print) -> dict[str, float]:
    """Env steps/s of the jitted batched step with and without the economics, side by side.

    ``num_envs=0``: the catalog's (capped to ``cpu_num_envs_cap`` when JAX has no GPU);
    ``steps_per_block=0``: 1,000 on a GPU, 20 on a CPU. Returns and prints the per-arm median
    steps/s, the median round ratio (with economics / without) and its range.
    """
    from econmotor.config.objective_profile import ObjectiveVector
    from econmotor.motor_backend.mjx.env import GymCourierEnv
    from econmotor.motor_backend.mjx.wrappers import make_env
    from econmotor.objectives.loader import objective_from_vector
    from econmotor.valuation import default_objective_vector

    objective = objective_from_vector(ObjectiveVector.from_list(default_objective_vector()), "default")
    econ = make_env(GymCourierEnv, task_id, objective=objective)
    bare = make_env(GymCourierEnv, task_id, objective=objective, economics=False)
    return side_by_side(task_id, econ, bare, ("with economics", "without"), num_envs, steps_per_block, rounds,
                        seed, print_fn, goal="goal >= 0.98")


def physics_throughput(task_id: str = TASK, num_envs: int = 0, steps_per_block: int = 0, rounds: int = 5,
                       seed: int = 0, print_fn=print) -> dict[str, float]:
    """Env steps/s of the jitted batched step (economics inside) with the body stepped by MuJoCo C from the
    step (``cpu_physics: mujoco``, ``mjx/host_physics.py``) against MJX, side by side; ratio C / MJX."""
    from econmotor.config.objective_profile import ObjectiveVector
    from econmotor.motor_backend.mjx.env import GymCourierEnv
    from econmotor.motor_backend.mjx.wrappers import make_env
    from econmotor.objectives.loader import objective_from_vector
    from econmotor.valuation import default_objective_vector

    objective = objective_from_vector(ObjectiveVector.from_list(default_objective_vector()), "default")
    host = make_env(GymCourierEnv, task_id, objective=objective, physics="mujoco")
    mjx = make_env(GymCourierEnv, task_id, objective=objective, physics="mjx")
    return side_by_side(task_id, host, mjx, ("MuJoCo C", "MJX"), num_envs, steps_per_block, rounds, seed, print_fn,
                        goal="on a CPU the faster is the task's cpu_physics")


def side_by_side(task_id: str, env_a, env_b, names: tuple[str, str], num_envs: int = 0, steps_per_block: int = 0,
                 rounds: int = 5, seed: int = 0, print_fn=print, goal: str = "") -> dict[str, float]:
    """Env steps/s of two envs' jitted batched steps (one ``lax.scan`` of random actions per block),
    in A B B A rounds; the ratio is A's rate over B's (median of the rounds, with the range)."""
    import jax
    import numpy as np

    on_gpu = jax.default_backend() == "gpu"
    if num_envs <= 0:
        s = env_a.settings
        num_envs = s.num_envs if on_gpu else min(s.num_envs, s.cpu_num_envs_cap)
    steps = steps_per_block or (1000 if on_gpu else 20)
    low, high = jax.numpy.asarray(env_a.action_low), jax.numpy.asarray(env_a.action_high)

    def runner(env):
        def run(state):
            def body(st, _):
                key = jax.random.fold_in(st.key[0], 7)
                action = jax.random.uniform(key, (num_envs, env.action_size), minval=low, maxval=high)
                return env.step(st, action), None

            state, _ = jax.lax.scan(body, state, None, length=steps)
            return state

        run = jax.jit(run)
        state = jax.jit(env.reset, static_argnums=1)(jax.random.PRNGKey(seed), num_envs)
        start = time.perf_counter()
        state = jax.block_until_ready(run(state))  # compile + one block
        return run, state, time.perf_counter() - start

    arms = {}
    for name, env in zip(names, (env_a, env_b), strict=True):
        arms[name] = list(runner(env))
        print_fn(f"{task_id}, {num_envs} envs on {jax.devices()[0].platform}: compiled the step ({name}) "
                 f"in {arms[name][2]:.0f} s", flush=True)

    def block(name: str) -> float:
        run, state, _ = arms[name]
        start = time.perf_counter()
        arms[name][1] = jax.block_until_ready(run(state))
        return time.perf_counter() - start

    a, b = names
    times: dict[str, list[float]] = {a: [], b: []}
    ratios = []
    for _ in range(rounds):
        b1, a1, a2, b2 = block(b), block(a), block(a), block(b)
        times[a] += [a1, a2]
        times[b] += [b1, b2]
        ratios.append((b1 + b2) / (a1 + a2))
    rate = {k: num_envs * steps / float(np.median(v)) for k, v in times.items()}
    out = {"a_steps_per_s": rate[a], "b_steps_per_s": rate[b], "ratio": float(np.median(ratios)),
           "ratio_min": min(ratios), "ratio_max": max(ratios), "num_envs": float(num_envs)}
    print_fn(f"env steps/s, {task_id}, {num_envs} envs x {steps} steps per block, {rounds} A B B A rounds: "
             f"{a} {rate[a]:,.0f}, {b} {rate[b]:,.0f}; ratio {out['ratio']:.3f} "
             f"(rounds {out['ratio_min']:.3f}-{out['ratio_max']:.3f}{'; ' + goal if goal else ''})", flush=True)
    return out


def _timed_progress() -> tuple[list[tuple[float, float]], object]:
    stamps: list[tuple[float, float]] = []

    def progress(label: str, done: float, total: float) -> None:
        if label == "train":
            stamps.append((time.perf_counter(), done))

    return stamps, progress


def _rate(stamps: list[tuple[float, float]]) -> float:
    """Steps/s from the second progress report (after the first iteration: compilation) to the last."""
    (t0, n0), (t1, n1) = stamps[1], stamps[-1]
    return (n1 - n0) / (t1 - t0) if t1 > t0 else float("nan")


def mjx_ppo_throughput(steps: int, num_envs: int, seed: int = 0) -> tuple[float, int, str]:
    """(env steps/s, num_envs used, device) of ``MjxBackend.train_policy`` after compilation."""
    from econmotor.motor_backend.mjx.backend import MjxBackend
    from econmotor.motor_backend.mjx.device import device_description
    from econmotor.objectives import EconomicObjectiveSpec

    backend = MjxBackend()
    stamps, progress = _timed_progress()
    with tempfile.TemporaryDirectory() as out:
        result = backend.train_policy(TASK, EconomicObjectiveSpec(), [], num_envs, steps, seed, output_dir=out,
                                      eval_episodes=0, progress=progress, select_every_steps=0)
    return _rate(stamps), int(result.config["num_envs"]), device_description()


def sb3_ppo_throughput(steps: int, seed: int = 0) -> tuple[float, int]:
    """(env steps/s, num_envs) of the mujoco backend's SB3 PPO (catalog num_envs, CPU)."""
    import torch

    from econmotor.motor_backend.mujoco.backend import MujocoBackend
    from econmotor.objectives import EconomicObjectiveSpec

    torch.set_num_threads(1)
    backend = MujocoBackend()
    stamps, progress = _timed_progress()
    with tempfile.TemporaryDirectory() as out:
        result = backend.train_policy(TASK, EconomicObjectiveSpec(), [], 0, steps, seed, output_dir=out,
                                      eval_episodes=0, progress=progress, algorithm="ppo", select_every_steps=0)
    return _rate(stamps), int(result.config["num_envs"])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--mjx-envs", type=int, default=0, help="0: the catalog's (capped on a CPU)")
    parser.add_argument("--mjx-steps", type=int, default=20_000_000)
    parser.add_argument("--sb3-steps", type=int, default=20_480)
    parser.add_argument("--skip-env-step", action="store_true", help="only the PPO comparison")
    parser.add_argument("--env-task", default=TASK, help="task of the env-step comparison")
    parser.add_argument("--env-envs", type=int, default=0, help="env-step envs (0: catalog, CPU-capped)")
    parser.add_argument("--env-steps", type=int, default=0, help="env-step block (0: 1000 GPU, 20 CPU)")
    parser.add_argument("--env-rounds", type=int, default=5, help="A B B A rounds of the env-step comparison")
    parser.add_argument("--physics", action="store_true", help="only the env step with MuJoCo C against MJX")
    args = parser.parse_args()
    if args.physics:
        physics_throughput(args.env_task, args.env_envs, args.env_steps, args.env_rounds)
        return
    if not args.skip_env_step:
        env_step_throughput(args.env_task, args.env_envs, args.env_steps, args.env_rounds)
    sb3, sb3_envs = sb3_ppo_throughput(args.sb3_steps)
    print(f"mujoco backend, SB3 PPO, {sb3_envs} CPU envs: {sb3:10,.0f} env steps/s", flush=True)
    mjx, mjx_envs, device = mjx_ppo_throughput(args.mjx_steps, args.mjx_envs)
    print(f"mjx backend, JAX PPO, {mjx_envs} envs on {device}: {mjx:10,.0f} env steps/s", flush=True)
    print(f"PPO training throughput ratio mjx / mujoco (SB3): {mjx / sb3:.2f}x "
          f"(goal on a GPU: >= 100x)")


if __name__ == "__main__":
    main()
