"""Wall seconds to a deployable demo hopper: the demo's learner against SB3's PPO on the mujoco backend, same run.

For each seed, one run per arm, each in a fresh process (so XLA compiles as on a fresh clone), one
after the other on this machine (both arms see the same hours):

- ``demo``: what ``econmotor demo`` runs (``cli/demo.py``): ``hopper_courier`` on the ``mjx`` backend
  (JAX PPO on 64 batched envs on a CPU, the Hopper-v5 body stepped by MuJoCo C: the task's ``cpu_physics``)
  under the demo's objective
  (``courier_demo.yaml``) and its PPO (``DEMO_HYPERPARAMETERS``), until a held-out evaluation (every 25,000
  env steps, at most ``DEMO_SELECT_EPISODES``, beside training, as the demo) passes the task's acceptance
  rule; JAX's compilation cache is an empty folder of its own unless ``--warm-cache`` (then the first seed
  fills one the others reuse);
- ``old``: the demo before it, the ``mujoco`` backend's SB3 PPO on 4 in-process envs (the catalog's
  hyperparameters: n_steps 512, batch 64, 10 epochs), a held-out evaluation every 25,000 env steps.

Each arm's policy is then evaluated like the demo's report (a sequential evaluation of fresh episodes,
seeds ``seed + 1000 ...``, apart from the held-out ones, until the verdict is decided; or exactly
``--eval-episodes N``) and judged by the report's judgement (``economics.uncertainty.judge``, as the
sequential plan's looks judge). Printed per seed and arm: env steps trained, training wall seconds
(``train_policy``: env creation, compilation, training, held-out evaluations, ONNX export), the
fresh evaluation's seconds, the report verdict with falls / legs and legs/h; then each arm's median
training seconds and their ratio. The load average is printed at the start and the end.

Tried and not kept for the SB3 arm (2 shared cores, 2026-11-25/28): PPO ``batch_size`` 256 ran
1.07-1.34x the env steps/s with 10 epochs (1.7x with 5), but seed 0 was still not deployable at 225k
steps (batch 256, 5 epochs: not at 600k); SB3's ``SubprocVecEnv`` for the 4 envs ran 0.51-0.62x the
steps/s of the in-process ``DummyVecEnv`` (pipes cost more than a Hopper step). For the demo arm, XLA
flags against the default (compilation 20.5 s, then 7,975 env steps/s; idle cores, 2026-11-28):
``--xla_backend_optimization_level=0`` 29.1 s and 73 steps/s, ``--xla_llvm_disable_expensive_passes``
23.3 s and 6,750, single-threaded Eigen 21.3 s and 7,416. The backend's own held-out cadence (at most a
tenth of the wall time) found seed 1's deployable policy at 600k steps in 94 s, every 25,000 steps at
225k in 57 s (warm cache). On 2026-11-29 (idle cores, seed 0, the demo arm's training alone): held-out
batches of 32 episodes instead of 16 kept the trajectory but cost 1.6-2.0 s a failing evaluation instead of
0.6-1.1 s (54.4 s to the pass against 51.8 s); the evaluator compiled from the start in a thread at nice 19
made the first iteration 21.6 s instead of 12.5 s (45.8 s against 42.2 s). Those figures are MJX's physics;
since then the hopper steps in MuJoCo C on a CPU (``cpu_physics``), and the held-out batch there is 48
(``CPU_EVAL_BATCH``: 25.0-34.0 s to the pass on seeds 0, 1 and 4 against 28.8-41.5 s with 16). For the demo's
PPO settings tried over seeds 0-4 (reward scaling, entropy bonus, epochs, unroll length, learning rate,
initial log-std), see ``benchmarks/RESULTS.md``.

    .venv/bin/python benchmarks/time_to_deployable.py [--seeds 0,1,2] [--arms demo,old] [--warm-cache]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import tempfile
import time

os.environ.setdefault("OMP_NUM_THREADS", "1")

from econmotor.cli.demo import (
    DEMO_BACKEND,
    DEMO_HYPERPARAMETERS,
    DEMO_MAX_STEPS,
    DEMO_OBJECTIVE,
    DEMO_SELECT_EPISODES,
    DEMO_SELECT_EVERY,
    DEMO_TASK,
)
from econmotor.economics.sequential_rule import SequentialPlan
from econmotor.motor_backend.factory import make_motor_backend
from econmotor.motor_backend.selection import Selection, SelectionConfig
from econmotor.motor_backend.sequential import evaluate_sequentially
from econmotor.objectives import load_objective_spec

REPORT_EVAL_OFFSET = 1_000  # the report's evaluation run: seed + 1000 + i (recording.train_and_record)
#: the old demo's learner: the mujoco backend's SB3 PPO, a held-out evaluation every this many env steps
OLD_BACKEND, OLD_SELECT_EVERY = "mujoco", 25_000
#: the smallest run (tests/integration/test_benchmarks.py): one seed, one iteration of each arm
SMOKE_ARGS: list[str] = ["--seeds", "0", "--max-steps", "64", "--select-episodes", "1", "--eval-episodes", "1"]


def run_arm(arm: str, seed: int, args: argparse.Namespace, out: str, cache_dir: str | None) -> dict:
    """One arm's run and its fresh evaluation (in a process of its own)."""
    if arm == "demo":
        backend = make_motor_backend(DEMO_BACKEND, compilation_cache_dir=cache_dir)
        every = DEMO_SELECT_EVERY
        given = json.loads(args.hyperparameters) if args.hyperparameters else DEMO_HYPERPARAMETERS
        hyperparameters = {"hyperparameters": given}
        episodes = args.select_episodes or DEMO_SELECT_EPISODES
    else:
        backend = make_motor_backend(OLD_BACKEND)
        every, hyperparameters, episodes = OLD_SELECT_EVERY, {}, args.select_episodes
    objective = load_objective_spec(DEMO_OBJECTIVE)
    task = backend.catalog.get(DEMO_TASK)
    run_dir = os.path.join(out, f"{arm}-s{seed}")
    started = time.perf_counter()
    result = backend.train_policy(DEMO_TASK, objective, [], 0, args.max_steps, seed, output_dir=run_dir,
                                  eval_episodes=0, until_deployable=True, select_every_steps=every,
                                  select_episodes=episodes, **hyperparameters)
    train_s = time.perf_counter() - started
    t_eval = time.perf_counter()
    if args.eval_episodes:
        evaluation = backend.evaluate_policy(result.policy_id, DEMO_TASK, objective, args.eval_episodes,
                                             seed + REPORT_EVAL_OFFSET)
        confidence, sequential, how = 0.95, False, f"fixed {args.eval_episodes}"
    else:
        plan = SequentialPlan(batch=backend.evaluation_batch(DEMO_TASK))
        evaluation = evaluate_sequentially(backend, result.policy_id, task, objective, plan, seed + REPORT_EVAL_OFFSET)
        seq = evaluation.config["sequential"]
        confidence, sequential, how = seq["confidence"], True, f"sequential: {seq['outcome']} at {seq['episodes']}"
    eval_s = time.perf_counter() - t_eval
    raw = [{k: v for k, v in ep.items()} for ep in evaluation.episodes]
    _, verdict, j_mean = Selection(task, objective, SelectionConfig()).judge(raw, confidence, sequential)
    falls = sum(float(e["errors"]) for e in raw)
    legs = sum(float(e["units_completed"]) for e in raw)
    hours = sum(float(e["episode_length_s"]) for e in raw) / 3600.0
    selection = result.config.get("selection") or {}
    return {"seed": seed, "arm": arm, "env_steps": int(result.config.get("trained_steps", result.config["max_steps"])),
            "train_s": round(train_s, 1),
            "compile_s": round((result.config.get("timing") or {}).get("first_iteration_s") or 0.0, 1),
            "env_steps_per_s": round(int(result.config.get("trained_steps", result.config["max_steps"])) / train_s),
            "held_out_deployable_at": selection.get("became_deployable"),
            "held_out_evals": (selection.get("evaluation_cost") or {}).get("count"),
            "held_out_eval_s": (selection.get("evaluation_cost") or {}).get("wall_s"),
            "report_verdict": verdict.label, "report_episodes": len(raw), "report_eval": how,
            "report_eval_s": round(eval_s, 1), "falls": falls, "legs": round(legs, 1),
            "legs_per_h": round(legs / hours, 1) if hours else 0.0, "J": round(j_mean, 2)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", default="0,1,2")
    parser.add_argument("--arms", default="demo,old")
    parser.add_argument("--max-steps", type=int, default=DEMO_MAX_STEPS, help="cap of each arm")
    parser.add_argument("--select-episodes", type=int, default=None, help="cap of a held-out evaluation "
                        "(default: the demo's DEMO_SELECT_EPISODES, the old arm's selection.DEFAULT_SELECT_EPISODES)")
    parser.add_argument("--eval-episodes", type=int, default=0, help="a fixed count (0: sequential, as the demo)")
    parser.add_argument("--hyperparameters", default=None, help="the demo arm's PPO over the catalog's, "
                        "as JSON (default: the demo's DEMO_HYPERPARAMETERS)")
    parser.add_argument("--warm-cache", action="store_true", help="the demo arm's runs share one compilation cache")
    args = parser.parse_args()
    seeds = [int(s) for s in args.seeds.split(",")]
    arms = args.arms.split(",")
    print(f"load average at start: {os.getloadavg()}, cpus {os.cpu_count()}; args {vars(args)}", flush=True)
    rows = []
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    with tempfile.TemporaryDirectory() as out:
        shared = os.path.join(out, "jax-cache")
        for seed in seeds:
            for arm in arms:  # interleaved: both arms see the same hours
                cache = shared if args.warm_cache else os.path.join(out, f"jax-cache-{arm}-{seed}")
                with ProcessPoolExecutor(1, mp_context=multiprocessing.get_context("spawn")) as pool:
                    rows.append(pool.submit(run_arm, arm, seed, args, out, cache).result())
                print(json.dumps(rows[-1]), flush=True)
    print(f"load average at end: {os.getloadavg()}")
    print(f"{'arm':<5} {'seed':>4} {'pass at':>8} {'train s':>8} {'compile':>8} {'eval s':>7} "
          f"{'verdict (fresh)':>15} {'falls/legs':>11} {'legs/h':>7}")
    for r in rows:
        at = (r["held_out_deployable_at"] or {}).get("env_steps")
        at = at if at is not None else "-"
        print(f"{r['arm']:<5} {r['seed']:>4} {at:>8} {r['train_s']:>8.1f} {r['compile_s']:>8.1f} "
              f"{r['report_eval_s']:>7.1f} {r['report_verdict']:>15} {r['falls']:>4.0f}/{r['legs']:<6.1f} "
              f"{r['legs_per_h']:>7.1f}")
    medians = {arm: statistics.median(r["train_s"] for r in rows if r["arm"] == arm) for arm in arms}
    for arm in arms:
        ok = sum(r["report_verdict"] == "deployable" for r in rows if r["arm"] == arm)
        print(f"{arm}: median training {medians[arm]:.1f} s; deployable on {ok} of {len(seeds)} seeds")
    if "demo" in medians and "old" in medians:
        print(f"ratio median demo / median old: {medians['demo'] / medians['old']:.2f}")


if __name__ == "__main__":
    main()
