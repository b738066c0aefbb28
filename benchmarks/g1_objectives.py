"""Does an objective buy cheaper labour on a real robot? The G1 fine-tuned on a CPU for two objectives.

Same start, different economics: the mujoco backend's CPU trainer fine-tunes one of Holosoma's shipped G1
walkers (``--start``, the PPO by default) under ``energy_saver`` and under ``throughput`` (``--presets``: any
objective YAML of ``configs/objectives``, such as ``price_weighted``), each with three training seeds
(``--seeds``), on the batched MuJoCo walker env that prices it, under ``configs/datapacks/humanoid_stress.yaml``,
for at most ``--minutes`` of wall time each (one run after the other, each stepping its robots on every core;
held-out selection included)::

    econmotor train --motor-backend mujoco --task-id humanoid_locomotion_g1 \\
        --init-policy holosoma:g1_29dof/ppo --objective-config configs/objectives/<preset>.yaml \\
        --datapacks configs/datapacks/humanoid_stress.yaml --max-minutes 30 --max-steps 100000000 \\
        --select-episodes 34 --eval-episodes 0 --seed <seed> --output-dir <work>/<preset>_s<seed>

The runs live in ``--work`` (``runs/g1_objectives`` by default): run again, an unfinished run resumes from its
checkpoint with what is left of its wall-time budget (the wall seconds of its curve's segments), a finished
one is kept.

Then ``econmotor compare`` prices every export beside both shipped G1 walkers on the same held-out seeds
(``seed + 1000 + i``: apart from the training seeds, 10,000,000 on, and selection's, 50,000 on), under
nominal conditions (``--nominal-episodes``, enough for a deployable verdict) and under the stress
datapack (``--stress-episodes``). Printed per condition and policy: legs/h, Wh per leg, falls in legs,
the fall rate's 90% upper bound per leg (Clopper-Pearson), price per leg and verdict; then, for each
fine-tune against the walker it started from, the paired differences (episode i of two policies on the
same seed, resampled together: 90% bootstrap intervals) of Wh per leg and legs per hour, the falls per leg
and an exact paired test of the falls (McNemar's, two-sided, on the seeds where one fell and the other
did not); the goals each meets, and compare's winner. The held-out looks of every run (J, falls) go to
``curves.png`` beside the figures.

Run (defaults: the committed exports in ``benchmarks/results/g1_objectives/``)::

    OMP_NUM_THREADS=1 .venv/bin/python benchmarks/g1_objectives.py
    OMP_NUM_THREADS=1 .venv/bin/python benchmarks/g1_objectives.py --train --minutes 30   # train them first
"""

from __future__ import annotations

import argparse
import json
import math
import os
import shutil
import subprocess
import sys
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path

import numpy as np

os.environ.setdefault("OMP_NUM_THREADS", "1")

REPO = Path(__file__).resolve().parents[1]
TASK = "humanoid_locomotion_g1"
SHIPPED = {"ppo": "holosoma:g1_29dof/ppo", "fastsac": "holosoma:g1_29dof/fastsac"}
PRESETS = ("energy_saver", "throughput")
#: the objectives a run may be trained for: every YAML of ``configs/objectives`` (``--presets``: their names)
OBJECTIVES = REPO / "configs" / "objectives"
#: the goal the issue sets each preset (another objective is shown every goal)
GOALS = {"energy_saver": ("energy_cut",), "throughput": ("faster",)}
STRESS = REPO / "configs" / "datapacks" / "humanoid_stress.yaml"
RESULTS = REPO / "benchmarks" / "results" / "g1_objectives"
RESAMPLES = 2000
#: the goals: energy_saver at least this share fewer Wh per leg than its start, falls under stress at most this
#: share of its start's
ENERGY_CUT, FALL_SHARE = 0.10, 0.5

#: the smallest run: one tiny fine-tune per preset, two episodes per policy and condition
#: (tests/integration/test_benchmarks.py)
SMOKE_ARGS: list[str] = ["--train", "--max-steps", "256", "--num-envs", "4", "--seeds", "0", "--nominal-episodes",
                         "2", "--stress-episodes", "2", "--results", "smoke-results", "--work", "smoke-work"]


def run_name(preset: str, seed: int) -> str:
    return f"{preset}_s{seed}"


def spent_wall_s(run_dir: Path) -> float:
    """The wall seconds a run's curve records, over its invocations (each restarts its clock)."""
    path, total, last = run_dir / "curve.jsonl", 0.0, 0.0
    if not path.is_file():
        return 0.0
    for line in path.read_text().splitlines():
        wall = float(json.loads(line)["wall_s"])
        if wall < last:  # a resumed invocation
            total += last
        last = wall
    return total + last


def train_command(preset: str, seed: int, out: Path, minutes: float, max_steps: int, num_envs: int | None,
                  start: str, resume: bool, hyperparameters: Sequence[str] = ()) -> list[str]:
    command = [sys.executable, "-m", "econmotor", "train", "--motor-backend", "mujoco", "--task-id", TASK,
               "--max-minutes", f"{minutes:.3f}", "--max-steps", str(max_steps), "--output-dir", str(out),
               "--db-url", f"sqlite:///{out.parent / 'train.sqlite'}"]
    if resume:
        return [*command, "--resume"]
    command += ["--init-policy", SHIPPED[start], "--objective-config", str(OBJECTIVES / f"{preset}.yaml"),
                "--datapacks", str(STRESS),
                "--select-episodes", "34", "--eval-episodes", "0", "--seed", str(seed)]
    command += [arg for item in hyperparameters for arg in ("--hyperparameters", item)]
    return command + (["--num-envs", str(num_envs)] if num_envs else [])


def trained_steps(run_dir: Path) -> int:
    """The env steps a run's curve records (0 before its first row)."""
    path = run_dir / "curve.jsonl"
    lines = path.read_text().splitlines() if path.is_file() else []
    return int(json.loads(lines[-1])["env_steps"]) if lines else 0


def train(args: argparse.Namespace, results: Path, work: Path) -> None:
    """The fine-tunes one after the other (a run collects on every core), an interrupted one resumed from its
    checkpoint with what is left of ``--minutes``; a complete run (stopped by its budget or its steps) is kept as
    it is (train further from its export in a new run); their exports, configs and curves to ``results``."""
    from econmotor.motor_backend.factory import backend_class

    results.mkdir(parents=True, exist_ok=True)
    for preset in args.presets:
        for seed in args.seeds:
            name = run_name(preset, seed)
            out = work / name
            left = args.minutes - spent_wall_s(out) / 60.0
            if backend_class("mujoco").is_complete_run(out):
                print(f"kept {name}: a complete run, {trained_steps(out):,} env steps", flush=True)
            elif left > 0.05 and trained_steps(out) < args.max_steps:
                resume = (out / "checkpoints" / "latest.pt").is_file()
                started = time.perf_counter()
                with (work / f"{name}.log").open("a") as log:
                    proc = subprocess.Popen(train_command(preset, seed, out, left, args.max_steps, args.num_envs,
                                                          args.start, resume, args.hyperparameters),
                                            stdout=log, stderr=subprocess.STDOUT, cwd=REPO)
                if proc.wait() != 0:
                    raise SystemExit(f"training {name} failed: see {work / f'{name}.log'}")
                print(f"trained {name}: {time.perf_counter() - started:.0f} s wall now, "
                      f"{spent_wall_s(out) / 60:.1f} min and {trained_steps(out):,} env steps in all", flush=True)
            for source, target in (("policy.onnx", ".onnx"), ("run_config.json", ".run_config.json"),
                                   ("curve.jsonl", ".curve.jsonl")):
                shutil.copy(out / source, results / f"{name}{target}")


def compare(policies: dict[str, str], episodes: int, stress: bool, work: Path) -> dict:
    """``econmotor compare`` of ``policies`` (name -> policy); its ranking and every policy's episodes."""
    from econmotor.cli import main
    from econmotor.store import Registry

    tag = "stress" if stress else "nominal"
    url = f"sqlite:///{work / f'compare-{tag}.sqlite'}"
    argv = ["compare", "--task-id", TASK, "--eval-episodes", str(episodes), "--seed", "0", "--db-url", url,
            "--output-dir", str(work / f"compare-{tag}")]
    for policy in policies.values():
        argv += ["--policy", policy]
    if stress:
        argv += ["--datapacks", str(STRESS)]
    started = time.perf_counter()
    if main(argv) != 0:
        raise SystemExit(f"compare ({tag}) failed")
    wall = time.perf_counter() - started
    result = json.loads((work / f"compare-{tag}" / "compare.json").read_text())
    with Registry(url, create=False) as reg:
        reports = {r.id: r for r in reg.reports(task_id=TASK)}
        by_policy = {}
        for row in result["ranking"]:
            run_id = reports[row["report_id"]].eval_run_id
            episodes_ = sorted(reg.episodes(run_ids=[run_id]), key=lambda e: e.summary.get("seed", 0))
            by_policy[row["policy"]] = {"row": row, "episodes": [e.summary for e in episodes_]}
    return {"wall_s": wall, "summary": result["summary"], "winner": result["ranking"][0]["policy"],
            "policies": by_policy}


def columns(episodes: list[dict]) -> tuple[np.ndarray, ...]:
    get = lambda key: np.array([float(e[key]) for e in episodes])
    return get("energy_wh"), get("units_completed"), get("episode_length_s") / 3600.0, get("errors")


def wh_per_leg(wh: np.ndarray, legs: np.ndarray, *_: np.ndarray) -> float:
    return float(wh.sum() / legs.sum()) if legs.sum() > 0 else float("inf")


def legs_per_hour(wh: np.ndarray, legs: np.ndarray, hours: np.ndarray, *_: np.ndarray) -> float:
    return float(legs.sum() / hours.sum())


def falls_per_leg(wh: np.ndarray, legs: np.ndarray, hours: np.ndarray, falls: np.ndarray) -> float:
    return float(falls.sum() / legs.sum()) if legs.sum() > 0 else float("inf")


def paired(stat, a: tuple[np.ndarray, ...], b: tuple[np.ndarray, ...], seed: int = 20261128) -> tuple[float, ...]:
    """``stat(a) - stat(b)`` and its 90% bootstrap interval, episodes resampled in pairs (same seeds)."""
    rng = np.random.default_rng(seed)
    n = min(len(a[0]), len(b[0]))
    picks = rng.integers(0, n, size=(RESAMPLES, n))
    values = [stat(*(c[p] for c in a)) - stat(*(c[p] for c in b)) for p in picks]
    return stat(*a) - stat(*b), float(np.quantile(values, 0.05)), float(np.quantile(values, 0.95))


def mcnemar_p(a_fell: np.ndarray, b_fell: np.ndarray) -> tuple[int, int, float]:
    """Exact two-sided McNemar test of paired falls: (seeds where only a fell, only b fell, p-value)."""
    only_a = int(np.sum((a_fell > 0) & (b_fell == 0)))
    only_b = int(np.sum((a_fell == 0) & (b_fell > 0)))
    n = only_a + only_b
    if n == 0:
        return only_a, only_b, 1.0
    tail = sum(math.comb(n, k) for k in range(min(only_a, only_b) + 1)) / 2.0 ** n
    return only_a, only_b, min(1.0, 2.0 * tail)


def fall_bound(episodes: list[dict]) -> float:
    from econmotor.economics.uncertainty import clopper_pearson

    _, legs, _, falls = columns(episodes)
    return clopper_pearson(falls.sum(), legs.sum() + falls.sum(), 0.90)[1]


def report(tag: str, cmp: dict, names: dict[str, str], starts: dict[str, str]) -> dict:
    """The condition's table, each fine-tune against the walker it started from, and the goals it meets."""
    print(f"\n{TASK}, {tag}: compare in {cmp['wall_s']:.0f} s")
    print(f"{'policy':<18}{'legs/h':>8}{'Wh/leg':>8}{'falls/legs':>12}{'fall<=90%':>10}{'USD/leg':>9}  verdict")
    out: dict = {"wall_s": cmp["wall_s"], "summary": cmp["summary"], "policies": {}, "paired": {}}
    for name, policy in names.items():
        entry = cmp["policies"][policy]
        cols, row = columns(entry["episodes"]), entry["row"]
        figures = {"legs_per_hour": legs_per_hour(*cols), "wh_per_leg": wh_per_leg(*cols),
                   "falls": float(cols[3].sum()), "legs": float(cols[1].sum()),
                   "fall_bound90": fall_bound(entry["episodes"]), "price_usd_per_leg": row["price_usd_per_unit"],
                   "verdict": row["verdict"], "deployable": row["deployable"], "episodes": len(entry["episodes"])}
        out["policies"][name] = figures
        falls = f"{figures['falls']:.0f}/{figures['legs']:.0f}"
        print(f"{name:<18}{figures['legs_per_hour']:>8.1f}{figures['wh_per_leg']:>8.3f}{falls:>12}"
              f"{figures['fall_bound90']:>10.4f}{figures['price_usd_per_leg']:>9.4f}  {row['verdict']}")
    eps = {name: columns(cmp["policies"][policy]["episodes"]) for name, policy in names.items()}
    for name, start in starts.items():
        a, b = eps[name], eps[start]
        wh, lph = paired(wh_per_leg, a, b), paired(legs_per_hour, a, b)
        only_a, only_b, p = mcnemar_p(a[3], b[3])
        share = wh[0] / wh_per_leg(*b)
        fpl_a, fpl_b = falls_per_leg(*a), falls_per_leg(*b)
        price = lambda n: out["policies"][n]["price_usd_per_leg"]
        goals = {"energy_cut": wh[0] <= -ENERGY_CUT * wh_per_leg(*b) and wh[2] < 0,
                 "faster": lph[1] > 0, "falls_no_more": a[3].sum() <= b[3].sum(),
                 "falls_halved": fpl_a <= FALL_SHARE * fpl_b, "cheaper": price(name) < price(start)}
        goals = {k: bool(v) for k, v in goals.items()}
        out["paired"][f"{name}-{start}"] = {"wh_per_leg": wh, "wh_share": share, "legs_per_hour": lph,
                                            "falls_per_leg": [fpl_a, fpl_b], "mcnemar": [only_a, only_b, p],
                                            "goals": goals}
        print(f"{name} - {start}: Wh/leg {wh[0]:+.3f} ({share:+.1%}; 90% {wh[1]:+.3f} to {wh[2]:+.3f}), "
              f"legs/h {lph[0]:+.1f} (90% {lph[1]:+.1f} to {lph[2]:+.1f}), falls/leg {fpl_a:.4f} vs "
              f"{fpl_b:.4f} (only one fell: {only_a} / {only_b} seeds, McNemar p {p:.3f})")
    tuned = [n for n in names if n not in SHIPPED]
    cheapest = min(tuned, key=lambda n: out["policies"][n]["price_usd_per_leg"]) if tuned else None
    winner = next(n for n, pol in names.items() if pol == cmp["winner"])
    out["cheapest_fine_tune"], out["winner"] = cheapest, winner
    if cheapest is not None:
        beats = all(out["policies"][cheapest]["price_usd_per_leg"] < out["policies"][s]["price_usd_per_leg"]
                    for s in SHIPPED)
        deployable = any(p["deployable"] for p in out["policies"].values())
        print(f"cheapest fine-tune {cheapest}: {out['policies'][cheapest]['price_usd_per_leg']:.4f} USD/leg, "
              f"{'cheaper' if beats else 'not cheaper'} than every shipped walker; ranked first by compare: {winner}"
              + ("" if deployable else " (no policy deployable on these episodes: no winner)"))
    print(cmp["summary"])
    return out


def goals_line(nominal: dict, stressed: dict, presets: list[str]) -> str:
    """One line per objective: the seeds that meet its goal (:data:`GOALS`; every one for an objective the issue
    sets none), nominal and under stress, then the seeds cheaper per leg than their start and those whose falls
    halved under stress."""
    lines = []
    for preset in presets:
        keys = [k for k in nominal["paired"] if k.startswith(preset + "_s")]
        if not keys:
            continue
        def met(cond: dict, goal: str, keys: list[str] = keys) -> int:
            return sum(bool(cond["paired"][k]["goals"][goal]) for k in keys)

        said = [f"{goal} on {met(nominal, goal)}/{len(keys)} seeds nominal, {met(stressed, goal)}/{len(keys)} under "
                "stress" for goal in GOALS.get(preset, ("energy_cut", "faster"))]
        lines.append(f"{preset}: {'; '.join(said)}; cheaper than its start on {met(nominal, 'cheaper')}/{len(keys)} "
                     f"nominal, {met(stressed, 'cheaper')}/{len(keys)} under stress; falls halved under stress on "
                     f"{met(stressed, 'falls_halved')}/{len(keys)}")
    return "\n".join(lines)


def plot_curves(results: Path, runs: list[str]) -> Path | None:
    """The held-out looks of each run (J, falls per episode, Wh per leg where the look recorded it) against env
    steps: ``results/curves.png``."""
    looks, kept = {}, {}
    for name in runs:
        path = results / f"{name}.run_config.json"
        selection = (json.loads(path.read_text()).get("selection") or {}) if path.is_file() else {}
        if selection.get("evaluations"):
            looks[name], kept[name] = selection["evaluations"], (selection.get("kept") or {}).get("env_steps")
    if not looks:
        return None
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    presets = sorted({name.rsplit("_s", 1)[0] for name in looks})
    fig, axes = plt.subplots(3, len(presets), figsize=(4.5 * len(presets), 8.5), sharex=True, squeeze=False)
    for name, evaluations in looks.items():
        top, bottom, energy = axes[:, presets.index(name.rsplit("_s", 1)[0])]
        steps = [e["env_steps"] / 1e6 for e in evaluations]
        line, = top.plot(steps, [e["j_mean"] for e in evaluations], marker="o", label=name)
        bottom.plot(steps, [e["errors"] / max(e["episodes"], 1) for e in evaluations], marker="o",
                    color=line.get_color())
        metered = [(x, e["energy_wh_per_unit"]) for x, e in zip(steps, evaluations, strict=True)
                   if e.get("energy_wh_per_unit") is not None]  # looks recorded before it was: none
        if metered:
            energy.plot(*zip(*metered, strict=True), marker="o", color=line.get_color())
        for e in evaluations:  # the kept look, ringed
            if e["env_steps"] == kept[name]:
                top.plot([e["env_steps"] / 1e6], [e["j_mean"]], "o", ms=12, mfc="none", color=line.get_color())
    for col, preset in enumerate(presets):
        axes[0, col].set_title(preset, fontsize=10)
        axes[0, col].legend(fontsize=7)
        axes[2, col].set_xlabel("env steps (millions)")
    axes[0, 0].set_ylabel("held-out J (mean)")
    axes[1, 0].set_ylabel("falls per episode")
    axes[2, 0].set_ylabel("Wh per leg (the look's episodes)")
    fig.suptitle("held-out looks\n(at 0 steps: the walker a run started from; ringed: the look kept)", fontsize=9)
    fig.tight_layout()
    out = results / "curves.png"
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--train", action="store_true", help="fine-tune every preset and seed first (else: the "
                        "exports in --results)")
    parser.add_argument("--minutes", type=float, default=30.0, help="wall-time budget of each fine-tune, in all")
    parser.add_argument("--max-steps", type=int, default=100_000_000)
    parser.add_argument("--num-envs", type=int, default=None, help="robots per run (default: the catalog's)")
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    parser.add_argument("--presets", nargs="+", default=list(PRESETS),
                        choices=sorted(path.stem for path in OBJECTIVES.glob("*.yaml")),
                        help="the objectives to fine-tune for (their YAML in configs/objectives)")
    parser.add_argument("--start", choices=sorted(SHIPPED), default="ppo", help="the shipped walker to start from")
    parser.add_argument("--hyperparameters", action="append", default=[], metavar="KEY=VALUE",
                        help="one setting of the learner's recipe for every new run (`econmotor train "
                        "--hyperparameters`; repeatable)")
    parser.add_argument("--nominal-episodes", type=int, default=120)
    parser.add_argument("--stress-episodes", type=int, default=60)
    parser.add_argument("--results", type=Path, default=RESULTS, help="where the exports are (and go)")
    parser.add_argument("--work", type=Path, default=REPO / "runs" / "g1_objectives",
                        help="the runs (kept: an unfinished one resumes)")
    return parser


def main() -> None:
    args = build_parser().parse_args()
    args.work, args.results = args.work.resolve(), args.results.resolve()  # the runs start in the repository
    args.work.mkdir(parents=True, exist_ok=True)
    if args.train:
        train(args, args.results, args.work)
    runs = [run_name(p, s) for p in args.presets for s in args.seeds
            if (args.results / f"{run_name(p, s)}.onnx").is_file()]
    if not runs:
        raise SystemExit(f"no exports in {args.results}: run with --train first")
    names = {n: str((args.results / f"{n}.onnx").resolve()) for n in runs} | SHIPPED
    starts = {n: args.start for n in runs}
    compare_dir = Path(tempfile.mkdtemp(prefix="g1-objectives-", dir=args.work))
    nominal = report("nominal", compare(names, args.nominal_episodes, False, compare_dir), names, starts)
    stressed = report("stress", compare(names, args.stress_episodes, True, compare_dir), names, starts)
    print("\n" + goals_line(nominal, stressed, args.presets))
    curves = plot_curves(args.results, runs)
    figures = compare_dir / "g1_objectives.json"
    figures.write_text(json.dumps({"nominal": nominal, "stress": stressed}, indent=2))
    print(f"\nfigures in {figures}" + (f"; held-out looks in {curves}" if curves else ""))


if __name__ == "__main__":
    main()
