"""XLA compilation and speed of the demo's jitted programs under XLA's defaults and under candidate CPU flags.

Each arm runs in a fresh process with JAX's persistent compilation cache off, one after the other, for
``--rounds`` rounds (alternating, so both see the same hours):

- ``flags``: ``XLA_FLAGS`` set to ``--flags`` (default :data:`CANDIDATE`);
- ``default``: ``XLA_FLAGS`` unset.

Measured on 2 idle cores (2026-11-28), the candidate (XLA's older elemental emitters instead of its MLIR fusion
emitters) compiled the iteration in 0.80x and the evaluation in 0.66x the time, and ran the iteration at 1.18x
the time: the demo's time to a deployable policy was no better with it (the seeds' PPO trajectories change
with the code XLA emits, and decide more), and a flag a newer XLA does not know aborts the process, so the
backend does not set it.

Per arm: the wall seconds to compile the demo's PPO iteration (``ppo.make_train_iteration``; hopper_courier,
64 envs, the demo's hyperparameters) and its held-out evaluation (``ppo.make_evaluate``, 16 envs), one after
the other, then the milliseconds per iteration over ``--iterations`` iterations; then the ratios.

    .venv/bin/python benchmarks/mjx_compile.py [--rounds 2] [--iterations 30]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time

#: the smallest run (tests/integration/test_benchmarks.py)
SMOKE_ARGS: list[str] = ["--rounds", "1", "--iterations", "1"]
#: XLA's older elemental emitters instead of its MLIR fusion emitters (XLA aborts on a flag it does not know)
CANDIDATE = "--xla_cpu_use_fusion_emitters=false"


def measure(iterations: int) -> dict:
    """One arm's figures, in this process (XLA_FLAGS set by the caller)."""
    import jax
    import jax.numpy as jnp

    from econmotor.cli.demo import DEMO_HYPERPARAMETERS, DEMO_OBJECTIVE, DEMO_TASK
    from econmotor.motor_backend.mjx import ppo
    from econmotor.motor_backend.mjx.backend import MjxBackend
    from econmotor.objectives import load_objective_spec

    backend = MjxBackend(compilation_cache_dir=None)
    env, _ = backend.env(DEMO_TASK, load_objective_spec(DEMO_OBJECTIVE))
    cfg = backend.ppo_config(backend.settings(DEMO_TASK), dict(DEMO_HYPERPARAMETERS))
    state = ppo.init_train_state(env, cfg, 64, 0)
    t = time.perf_counter()
    iteration = ppo.make_train_iteration(env, cfg, 64).lower(state, 1.0).compile()
    compile_iteration = time.perf_counter() - t
    t = time.perf_counter()
    ppo.make_evaluate(env, cfg, 16).lower(state.learner.params, state.learner.stats, jax.random.PRNGKey(0)).compile()
    compile_evaluate = time.perf_counter() - t
    state, metrics = iteration(jax.tree_util.tree_map(jnp.copy, state), 1.0)
    jax.block_until_ready(metrics)
    t = time.perf_counter()
    for _ in range(iterations):
        state, metrics = iteration(state, 1.0)
    jax.block_until_ready(metrics)
    per_iteration = (time.perf_counter() - t) / iterations
    return {"xla_flags": os.environ.get("XLA_FLAGS", ""), "compile_iteration_s": round(compile_iteration, 2),
            "compile_evaluate_s": round(compile_evaluate, 2), "iteration_ms": round(1e3 * per_iteration, 1),
            "env_steps_per_s": round(64 * cfg.unroll_length / per_iteration)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=2)
    parser.add_argument("--iterations", type=int, default=30)
    parser.add_argument("--flags", default=CANDIDATE, help="the XLA_FLAGS of the flags arm")
    parser.add_argument("--measure", action="store_true", help=argparse.SUPPRESS)  # one arm, in a child
    args = parser.parse_args()
    if args.measure:
        print(json.dumps(measure(args.iterations)))
        return
    arms = {"flags": args.flags, "default": None}
    print(f"load average at start: {os.getloadavg()}, cpus {os.cpu_count()}", flush=True)
    rows: dict[str, list[dict]] = {arm: [] for arm in arms}
    for _ in range(args.rounds):
        for arm, flags in arms.items():
            env = {k: v for k, v in os.environ.items() if k != "XLA_FLAGS"}
            env.update({"OMP_NUM_THREADS": "1", **({"XLA_FLAGS": flags} if flags else {})})
            out = subprocess.run([sys.executable, __file__, "--measure", "--iterations", str(args.iterations)],
                                 env=env, capture_output=True, text=True, check=True).stdout
            rows[arm].append(json.loads(out.strip().splitlines()[-1]))
            print(arm, json.dumps(rows[arm][-1]), flush=True)
    print(f"load average at end: {os.getloadavg()}")
    med = {arm: {k: statistics.median(r[k] for r in rs) for k in ("compile_iteration_s", "compile_evaluate_s",
                                                                   "iteration_ms")} for arm, rs in rows.items()}
    for arm, m in med.items():
        print(f"{arm:<8} compile iteration {m['compile_iteration_s']:5.1f} s, "
              f"evaluate {m['compile_evaluate_s']:5.1f} s, iteration {m['iteration_ms']:6.1f} ms "
              f"(medians of {args.rounds})")
    for k in ("compile_iteration_s", "compile_evaluate_s", "iteration_ms"):
        print(f"ratio flags / default, {k}: {med['flags'][k] / med['default'][k]:.2f}")


if __name__ == "__main__":
    main()
