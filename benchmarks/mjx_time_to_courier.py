"""Wall seconds from the start of the command until the humanoid courier does the human's job.

Goal reached when a deterministic evaluation of ``--eval-episodes`` (10) episodes shows no falls
and at least the human's legs per hour (the task catalog's ``mp_human_units_per_hour``: 468 legs
of 10 m per hour for humanoid_courier). The clock starts when this script starts, so JAX import,
MJX model load and XLA compilation count. Training is the mjx backend's JAX PPO
(``motor_backend/mjx/ppo.py``) with the catalog's hyperparameters; every ``--eval-every-steps``
env steps the policy is evaluated and one line is printed. Stops at the goal, at ``--max-steps``
or at ``--deadline-s`` and says which, honestly. Goal on one H100: under 90 s.

    .venv/bin/python benchmarks/mjx_time_to_courier.py                       # a GPU: the real run
    .venv/bin/python benchmarks/mjx_time_to_courier.py --num-envs 16 --deadline-s 600   # tiny, CPU
"""

from __future__ import annotations

import time

START = time.perf_counter()  # before the heavy imports: compilation and imports count

import argparse  # noqa: E402
import os  # noqa: E402

# single-threaded Eigen inside XLA's CPU kernels: measured 172 vs 137 hopper env steps/s (8 envs, 2 cores)
os.environ.setdefault("XLA_FLAGS", "--xla_cpu_multi_thread_eigen=false intra_op_parallelism_threads=1")

import jax  # noqa: E402

from econmotor.motor_backend.mjx import ppo  # noqa: E402
from econmotor.motor_backend.mjx.backend import MjxBackend  # noqa: E402
from econmotor.motor_backend.mjx.device import device_description  # noqa: E402
from econmotor.motor_backend.mjx.training import evaluate_episodes  # noqa: E402
from econmotor.motor_backend.results import summarize_episodes  # noqa: E402
from econmotor.objectives import EconomicObjectiveSpec  # noqa: E402

#: the smallest run (tests/integration/test_benchmarks.py): the hopper (compiles in a fraction of the
#: humanoid's time), one env, one evaluation of one episode after one PPO iteration
SMOKE_ARGS: list[str] = ["--task-id", "hopper_courier", "--num-envs", "1", "--max-steps", "20",
                         "--eval-every-steps", "20", "--eval-episodes", "1"]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--task-id", default="humanoid_courier")
    parser.add_argument("--num-envs", type=int, default=0, help="0: the catalog's (capped on a CPU)")
    parser.add_argument("--max-steps", type=int, default=100_000_000)
    parser.add_argument("--eval-every-steps", type=int, default=2_000_000)
    parser.add_argument("--eval-episodes", type=int, default=10)
    parser.add_argument("--deadline-s", type=float, default=900.0, help="give up after this many wall seconds")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--hidden-sizes", type=int, nargs="*", default=None, help="override the catalog's")
    args = parser.parse_args()

    backend = MjxBackend(eval_batch=args.eval_episodes, compilation_cache_dir=None)  # cold: every compile counts
    settings = backend.settings(args.task_id)
    human_legs_per_hour = backend.catalog.get(args.task_id).economics.mp_human_units_per_hour
    env, _ = backend.env(args.task_id, EconomicObjectiveSpec())
    overrides = {"hidden_sizes": args.hidden_sizes} if args.hidden_sizes else None
    cfg = backend.ppo_config(settings, overrides)
    num_envs, note = backend.resolve_num_envs(settings, args.num_envs)
    cfg, note = backend.fit_minibatches(cfg, num_envs, note, overrides)
    print(f"{args.task_id} on {device_description()}: {num_envs} envs ({note}), goal: 0 falls in "
          f"{args.eval_episodes} episodes and >= {human_legs_per_hour:g} legs/h", flush=True)
    state = ppo.init_train_state(env, cfg, num_envs, args.seed)
    first_s = float("nan")
    iteration = ppo.make_train_iteration(env, cfg, num_envs)
    evaluate = ppo.make_evaluate(env, cfg, args.eval_episodes)
    per_iteration = num_envs * cfg.unroll_length
    steps, next_eval, verdict, last = 0, args.eval_every_steps, "max-steps reached", None
    print(f"{'wall_s':>8} {'env_steps':>11} {'steps/s':>9} {'falls':>5} {'legs/h':>8} {'return':>8}", flush=True)
    t_prev, s_prev = time.perf_counter(), 0
    while steps < args.max_steps:
        state, metrics = iteration(state)
        steps += per_iteration
        if steps == per_iteration:
            jax.block_until_ready(metrics)
            first_s = time.perf_counter() - START
        if time.perf_counter() - START >= args.deadline_s:  # no evaluation (its compilation) past the deadline
            jax.block_until_ready(metrics)
            verdict = f"deadline of {args.deadline_s:g} s reached"
            break
        if steps < next_eval:
            continue
        jax.block_until_ready(metrics)
        next_eval = (steps // args.eval_every_steps + 1) * args.eval_every_steps
        rate = (steps - s_prev) / (time.perf_counter() - t_prev)
        rows = evaluate_episodes(evaluate, args.eval_episodes, env, state.learner, args.eval_episodes, args.seed + 1)
        raw, econ, _ = summarize_episodes(rows, backend.catalog.get(args.task_id).economics)
        last = (round(raw["errors"]), econ["mpl_units_per_hour"])
        print(f"{time.perf_counter() - START:8.1f} {steps:11,d} {rate:9,.0f} {last[0]:5d} {last[1]:8.1f} "
              f"{raw['return']:8.1f}", flush=True)
        t_prev, s_prev = time.perf_counter(), steps
        if last[0] == 0 and last[1] >= human_legs_per_hour:
            verdict = "GOAL"
            break
    wall = time.perf_counter() - START
    if verdict == "GOAL":
        print(f"time to courier: {wall:.1f} s wall (compilation included), {steps:,d} env steps, "
              f"{last[0]} falls, {last[1]:.0f} legs/h >= {human_legs_per_hour:g}")
    else:
        seen = f"last evaluation {last[0]} falls, {last[1]:.0f} legs/h" if last else "no evaluation finished"
        print(f"goal NOT reached ({verdict}) after {wall:.1f} s wall and {steps:,d} env steps "
              f"(first iteration, compilation included, done at {first_s:.1f} s): {seen} "
              f"(goal 0 falls, >= {human_legs_per_hour:g} legs/h)")


if __name__ == "__main__":
    main()
