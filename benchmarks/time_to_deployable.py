"""Wall seconds to a deployable demo hopper: train --until-deployable vs the fixed 300k-step run, same run.

For each seed, one after the other in this process (so both arms see the same machine):

- ``until``: ``hopper_courier`` under the demo's objective (``courier_demo.yaml``), evaluation-driven
  training (``motor_backend/selection.py``): a held-out evaluation of ``--select-episodes`` episodes
  every ``--select-every`` env steps, stop at the first that passes the task's acceptance rule, or
  at ``--max-steps``;
- ``fixed``: today's demo before this change, ``--baseline-steps`` (300k) steps, last weights kept.

Each arm's policy is then evaluated like the demo's report (a sequential evaluation of fresh episodes,
seeds ``seed + 1000 ...``, apart from the held-out ones, until the verdict is decided; or exactly
``--eval-episodes N``) and judged by the report's judgement (``economics.uncertainty.judge``, as the
sequential plan's looks judge). Printed per seed and arm: env steps trained, training wall
seconds (``train_policy``: env creation, training, held-out evaluations, ONNX export), the report
verdict with falls / legs and legs/h; then the median training seconds of each arm and their ratio.
The load average is printed at the start and the end: absolute seconds on a shared machine are
noisy, the ratio less so. ``--jobs 2`` runs two at once (seed by seed, arms interleaved), so each
run's seconds are those of a machine also running the other. ``--hp '{"batch_size": 256}'`` tries
other PPO hyperparameters in ``until``.

Tried and not kept (2 shared cores, 2026-11-25): PPO ``batch_size`` 256 instead of the catalog's 64
ran 1.07-1.34x the env steps/s, but seed 0's held-out fall-rate bound was still 0.97 at 225k steps
(0.046, deployable, with 64); SB3's ``SubprocVecEnv`` for the 4 envs ran 0.51-0.62x the steps/s of
the in-process ``DummyVecEnv`` (pipes cost more than a Hopper step), 16k-step runs side by side.

    OMP_NUM_THREADS=1 .venv/bin/python benchmarks/time_to_deployable.py [--seeds 0,1,2] [--arms until,fixed]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import tempfile
import time

os.environ.setdefault("OMP_NUM_THREADS", "1")

from econmotor.cli.demo import DEMO_MAX_STEPS, DEMO_OBJECTIVE, DEMO_TASK
from econmotor.economics.uncertainty import SequentialPlan
from econmotor.motor_backend.factory import make_motor_backend
from econmotor.motor_backend.selection import Selection, SelectionConfig
from econmotor.motor_backend.sequential import evaluate_sequentially
from econmotor.objectives import load_objective_spec

REPORT_EVAL_OFFSET = 1_000  # the report's evaluation run: seed + 1000 + i (recording.train_and_record)
#: the smallest run (tests/integration/test_benchmarks.py): one seed; ``until`` one PPO iteration of 4 x 16
#: steps, ``fixed`` one of the catalog's (4 x 512: --hp is the until arm's only)
SMOKE_ARGS: list[str] = ["--seeds", "0", "--max-steps", "64", "--baseline-steps", "64", "--select-every", "64",
                         "--select-episodes", "1", "--eval-episodes", "1", "--hp", '{"n_steps": 16, "n_epochs": 1}']


def run_arm(arm: str, seed: int, args: argparse.Namespace, out: str) -> dict:
    backend = make_motor_backend("mujoco")
    objective = load_objective_spec(DEMO_OBJECTIVE)
    task = backend.catalog.get(DEMO_TASK)
    until = arm == "until"
    options = dict(until_deployable=True, select_every_steps=args.select_every, select_episodes=args.select_episodes,
                   hyperparameters=json.loads(args.hp) or None) if until else dict(select_every_steps=0)
    run_dir = os.path.join(out, f"{arm}-s{seed}")
    started = time.perf_counter()
    result = backend.train_policy(DEMO_TASK, objective, [], 0, args.max_steps if until else args.baseline_steps,
                                  seed, output_dir=run_dir, eval_episodes=0, **options)
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
    parser.add_argument("--arms", default="until,fixed")
    parser.add_argument("--max-steps", type=int, default=DEMO_MAX_STEPS, help="cap of the until arm")
    parser.add_argument("--baseline-steps", type=int, default=300_000)
    parser.add_argument("--select-every", type=int, default=25_000)
    parser.add_argument("--select-episodes", type=int, default=None, help="cap of a held-out evaluation "
                        "(default: selection.DEFAULT_SELECT_EPISODES)")
    parser.add_argument("--eval-episodes", type=int, default=0, help="a fixed count (0: sequential, as the demo)")
    parser.add_argument("--hp", default="{}", help="JSON PPO hyperparameter overrides of the until arm")
    parser.add_argument("--jobs", type=int, default=1, help="runs at once (2: one per core; the arms of a seed "
                        "side by side)")
    args = parser.parse_args()
    seeds = [int(s) for s in args.seeds.split(",")]
    arms = args.arms.split(",")
    print(f"load average at start: {os.getloadavg()}, cpus {os.cpu_count()}; args {vars(args)}", flush=True)
    rows = []
    jobs = [(arm, seed) for seed in seeds for arm in arms]  # interleaved: both arms see the same hours
    with tempfile.TemporaryDirectory() as out:
        if args.jobs == 1:
            for arm, seed in jobs:
                rows.append(run_arm(arm, seed, args, out))
                print(json.dumps(rows[-1]), flush=True)
        else:
            import multiprocessing
            from concurrent.futures import ProcessPoolExecutor, as_completed

            with ProcessPoolExecutor(args.jobs, mp_context=multiprocessing.get_context("spawn")) as pool:
                futures = [pool.submit(run_arm, arm, seed, args, out) for arm, seed in jobs]
                for future in as_completed(futures):
                    rows.append(future.result())
                    print(json.dumps(rows[-1]), flush=True)
            rows.sort(key=lambda r: (r["seed"], arms.index(r["arm"])))
    print(f"load average at end: {os.getloadavg()}")
    print(f"{'arm':<6} {'seed':>4} {'env steps':>10} {'train s':>8} {'verdict (fresh)':>16} {'episodes':>8} "
          f"{'falls/legs':>11} {'legs/h':>7}")
    for r in rows:
        print(f"{r['arm']:<6} {r['seed']:>4} {r['env_steps']:>10,} {r['train_s']:>8.1f} {r['report_verdict']:>16} "
              f"{r['report_episodes']:>8} {r['falls']:>4.0f}/{r['legs']:<6.1f} {r['legs_per_h']:>7.1f}")
    medians = {arm: statistics.median(r["train_s"] for r in rows if r["arm"] == arm) for arm in arms}
    for arm in arms:
        ok = sum(r["report_verdict"] == "deployable" for r in rows if r["arm"] == arm)
        print(f"{arm}: median training {medians[arm]:.1f} s; deployable on {ok} of {len(seeds)} seeds")
    if "until" in medians and "fixed" in medians:
        print(f"ratio median fixed / median until: {medians['fixed'] / medians['until']:.2f}x")


if __name__ == "__main__":
    main()
