"""The timeline of a small mjx courier run, before and after issue 33, side by side in one run.

Three arms, each a fresh process training the same small run (``--task-id``, ``--num-envs``,
``--max-steps``, seed 0, the catalog's PPO; held-out evaluations at each backend's default
cadence; then ``--eval-episodes`` deterministic episodes evaluated twice, the second timed):

- ``before``: the code of ``--before-ref`` (default ``main``), checked out into a temporary git
  worktree and imported from there (``PYTHONPATH``), with a cold compilation cache;
- ``after``: this checkout's code, with a cold compilation cache;
- ``after-warm``: this checkout's code again, on the cache the ``after`` arm filled (a second run).

Printed per arm: the first training iteration (XLA compilation included), each held-out evaluation
(at env steps, its wall seconds, episodes and outcome), training's wall seconds, the held-out
evaluations' share of them, and the evaluation's seconds per episode (compiled, second call). The
load average is printed at the start and the end (the machine is shared).

    OMP_NUM_THREADS=1 .venv/bin/python benchmarks/mjx_eval_timeline.py [--max-steps 100000] [--num-envs 16]

Measured 2026-11-26 on the shared 2-core CPU (load 7-20, so absolute seconds are several times an idle
machine's), hopper_courier, 16 envs, 100k steps: before, the first iteration 783 s, then 4 held-out
evaluations (at 25k, 50k, 75k, 100k steps, 10 episodes each, cut short) cost 263 s, 20% of the 1,335 s
of training, 251 s of it the evaluation's own compile at its first use; after, the evaluation compiled
in a thread during the first iteration (714 s), and with the share rule as first written (evaluations
under 10% of the time since the start) 31 held-out evaluations cost 175 s, 11%, 25 of them in the 130 s
after the compile; the rule now spaces them from the last one (9x its cost of training between): a
separate cold run (load 7-14) made 12 held-out evaluations of 1.0-13.2 s, 32 s, 6.3% of its 516 s. A
second run on the first one's cache said "compilation cache warm: 3 compiled program(s) loaded ..." and
its first iteration took 156 s instead of 714 s. Evaluation per episode (compiled, 64 episodes): 81 ms
before (batch 10), 61.6 ms after (batch 16, episodes 202 steps long on average); the kept policies differ,
so per-episode times are not a like-for-like comparison; on a CPU a step costs in proportion to the batch.
The GPU timeline is not measured yet.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


#: the smallest run; HEAD as the 'before' (a CI clone may have no main branch)
SMOKE_ARGS: list[str] = ["--num-envs", "1", "--max-steps", "20", "--eval-episodes", "1", "--before-ref", "HEAD"]


def arm(args: argparse.Namespace) -> dict:
    """One arm, in this process (``econmotor`` from ``PYTHONPATH``): the run's timeline as a dict."""
    started = time.perf_counter()
    from econmotor.motor_backend.mjx.backend import MjxBackend
    from econmotor.motor_backend.mjx.device import device_description
    from econmotor.objectives import EconomicObjectiveSpec

    messages: list[str] = []

    def progress(label: str, done: float, total: float) -> None:
        if len(label) > 40 and label not in messages:
            messages.append(label)

    backend = MjxBackend(compilation_cache_dir=args.cache, runs_dir=args.out)
    objective = EconomicObjectiveSpec()
    result = backend.train_policy(args.task_id, objective, [], args.num_envs, args.max_steps, 0, eval_episodes=0,
                                  progress=progress)
    timing, selection = result.config["timing"], result.config.get("selection") or {}
    backend.evaluate_policy(result.policy_id, args.task_id, objective, args.eval_episodes, 1000)  # compiled now
    t0 = time.perf_counter()
    evaluation = backend.evaluate_policy(result.policy_id, args.task_id, objective, args.eval_episodes, 1000)
    eval_s = time.perf_counter() - t0
    return {"device": device_description(), "first_iteration_s": timing["first_iteration_s"],
            "train_wall_s": timing["train_wall_s"], "steps": timing["total_steps"],
            "held_out": [{k: e.get(k) for k in ("env_steps", "wall_s", "eval_s", "episodes", "outcome", "cut_short")}
                         for e in selection.get("evaluations", [])],
            "held_out_s": (selection.get("evaluation_cost") or {}).get("wall_s", 0.0),
            "eval_episodes": len(evaluation.episodes), "eval_s": eval_s,
            "eval_env_steps": sum(float(e.get("length_steps", 0.0)) for e in evaluation.episodes),
            "eval_s_per_episode": eval_s / max(len(evaluation.episodes), 1),
            "eval_batch": backend.evaluation_batch(args.task_id), "cache_hits": timing.get("compile_cache_hits"),
            "messages": [m for m in messages if "cache" in m], "process_s": time.perf_counter() - started}


def run_arm(name: str, src: Path, cache: str, args: argparse.Namespace, out: str) -> dict:
    env = {**os.environ, "PYTHONPATH": str(src), "OMP_NUM_THREADS": "1"}
    env.setdefault("XLA_FLAGS", "--xla_cpu_multi_thread_eigen=false intra_op_parallelism_threads=1")
    result_file = Path(out) / f"{name}.json"
    cmd = [sys.executable, str(Path(__file__).resolve()), "--arm", "--cache", cache, "--out", str(Path(out) / name),
           "--json", str(result_file), "--task-id", args.task_id, "--num-envs", str(args.num_envs),
           "--max-steps", str(args.max_steps), "--eval-episodes", str(args.eval_episodes)]
    proc = subprocess.run(cmd, env=env, cwd=out, capture_output=True, text=True)
    if proc.returncode != 0:
        raise SystemExit(f"arm {name} failed:\n{proc.stderr[-3000:]}")
    return json.loads(result_file.read_text())


def show(name: str, r: dict) -> None:
    share = r["held_out_s"] / r["train_wall_s"] if r["train_wall_s"] else 0.0
    print(f"--- {name} ({r['device']}, eval batch {r['eval_batch']}, cache hits {r['cache_hits']})")
    print(f"  first iteration (compile) {r['first_iteration_s']:7.1f} s")
    for e in r["held_out"]:
        print(f"  held-out @{e['env_steps']:>8,} steps  at {e['wall_s']:7.1f} s  took {e['eval_s']:6.2f} s  "
              f"{e['episodes']:>4} episodes  {e.get('outcome') or ('cut short' if e['cut_short'] else 'full')}")
    print(f"  training {r['steps']:,} steps: {r['train_wall_s']:.1f} s, held-out evaluations {r['held_out_s']:.1f} s "
          f"({share:.0%} of it)")
    steps = r.get("eval_env_steps") or 0.0
    print(f"  evaluation: {r['eval_episodes']} episodes in {r['eval_s']:.2f} s = {r['eval_s_per_episode'] * 1000:.1f} "
          f"ms per episode (compiled), episodes {steps / max(r['eval_episodes'], 1):.0f} steps long on average "
          "(the kept policies differ between arms)")
    for m in r["messages"]:
        print(f"  said: {m}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--task-id", default="hopper_courier")
    parser.add_argument("--num-envs", type=int, default=16)
    parser.add_argument("--max-steps", type=int, default=100_000)
    parser.add_argument("--eval-episodes", type=int, default=64)
    parser.add_argument("--before-ref", default="main")
    parser.add_argument("--arm", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("--cache", help=argparse.SUPPRESS)
    parser.add_argument("--out", help=argparse.SUPPRESS)
    parser.add_argument("--json", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.arm:
        Path(args.json).write_text(json.dumps(arm(args)))
        return
    print(f"load average at start: {os.getloadavg()}; {args.task_id}, {args.num_envs} envs, {args.max_steps:,} "
          f"steps; before = {args.before_ref}", flush=True)
    with tempfile.TemporaryDirectory() as out:
        before_tree = Path(out) / "before"
        subprocess.run(["git", "-C", str(REPO), "worktree", "add", "--detach", str(before_tree), args.before_ref],
                       check=True, capture_output=True)
        try:
            rows = {"before": run_arm("before", before_tree / "src", str(Path(out) / "cache-before"), args, out)}
            show("before", rows["before"])
            rows["after"] = run_arm("after", REPO / "src", str(Path(out) / "cache-after"), args, out)
            show("after", rows["after"])
            rows["after-warm"] = run_arm("after-warm", REPO / "src", str(Path(out) / "cache-after"), args, out)
            show("after-warm (second run, same cache)", rows["after-warm"])
        finally:
            subprocess.run(["git", "-C", str(REPO), "worktree", "remove", "--force", str(before_tree)],
                           capture_output=True)
    b, a = rows["before"], rows["after"]
    print(f"load average at end: {os.getloadavg()}")
    print(f"evaluation per episode: before {b['eval_s_per_episode'] * 1000:.1f} ms, after "
          f"{a['eval_s_per_episode'] * 1000:.1f} ms (ratio {b['eval_s_per_episode'] / a['eval_s_per_episode']:.2f}x)")
    for name, r in rows.items():
        print(f"{name}: held-out share {r['held_out_s'] / r['train_wall_s']:.0%} of {r['train_wall_s']:.0f} s "
              f"training, first iteration {r['first_iteration_s']:.1f} s")


if __name__ == "__main__":
    main()
