"""Does an objective buy cheaper labour on a real robot? The G1 fine-tuned on a CPU for two objectives.

Same start, different economics: the mujoco backend's CPU trainer fine-tunes Holosoma's shipped G1 PPO
walker (``--init-policy holosoma:g1_29dof/ppo``) under ``energy_saver`` and under ``throughput``, on the
batched MuJoCo walker env that prices it, under ``configs/datapacks/humanoid_stress.yaml``, for at most
``--minutes`` of wall time each (one run after the other, each stepping its robots on every core; held-out
selection included)::

    econmotor train --motor-backend mujoco --task-id humanoid_locomotion_g1 \\
        --init-policy holosoma:g1_29dof/ppo --objective-config configs/objectives/<preset>.yaml \\
        --datapacks configs/datapacks/humanoid_stress.yaml --max-minutes 58 --max-steps 100000000 \\
        --select-episodes 32 --eval-episodes 0 --seed 0 --output-dir runs/g1_ft_<preset>

Then ``econmotor compare`` prices both exports beside both shipped G1 walkers on the same held-out seeds
(``seed + 1000 + i``: apart from the training seeds, 10,000,000 on, and selection's, 50,000 on), under
nominal conditions (``--nominal-episodes``, enough for a deployable verdict) and under the stress
datapack (``--stress-episodes``). Printed per condition and policy: legs/h, Wh per leg, falls in legs,
the fall rate's 90% upper bound per leg (Clopper-Pearson), price per leg and verdict; then the paired
differences (episode i of two policies on the same seed, resampled together: 90% bootstrap intervals)
of each fine-tune against the shipped PPO and of energy_saver against throughput, and compare's winner.

Run (defaults: the committed exports in ``benchmarks/results/g1_objectives/``)::

    OMP_NUM_THREADS=1 .venv/bin/python benchmarks/g1_objectives.py
    OMP_NUM_THREADS=1 .venv/bin/python benchmarks/g1_objectives.py --train --minutes 58   # train them first
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

os.environ.setdefault("OMP_NUM_THREADS", "1")

REPO = Path(__file__).resolve().parents[1]
TASK = "humanoid_locomotion_g1"
SHIPPED = {"ppo": "holosoma:g1_29dof/ppo", "fastsac": "holosoma:g1_29dof/fastsac"}
PRESETS = ("energy_saver", "throughput")
STRESS = REPO / "configs" / "datapacks" / "humanoid_stress.yaml"
RESULTS = REPO / "benchmarks" / "results" / "g1_objectives"
RESAMPLES = 2000

#: the smallest run: two tiny fine-tunes, two episodes per policy and condition (tests/integration/test_benchmarks.py)
SMOKE_ARGS: list[str] = ["--train", "--max-steps", "256", "--num-envs", "4", "--nominal-episodes", "2",
                         "--stress-episodes", "2", "--results", "smoke-results"]


def train_command(preset: str, out: Path, minutes: float, max_steps: int, num_envs: int | None) -> list[str]:
    command = [sys.executable, "-m", "econmotor", "train", "--motor-backend", "mujoco", "--task-id", TASK,
               "--init-policy", SHIPPED["ppo"], "--objective-config", str(REPO / "configs" / "objectives" /
                                                                           f"{preset}.yaml"),
               "--datapacks", str(STRESS), "--max-minutes", str(minutes), "--max-steps", str(max_steps),
               "--select-episodes", "32", "--eval-episodes", "0", "--seed", "0", "--output-dir", str(out),
               "--db-url", f"sqlite:///{out.parent / 'train.sqlite'}"]
    return command + (["--num-envs", str(num_envs)] if num_envs else [])


def train(args: argparse.Namespace, results: Path, work: Path) -> None:
    """The fine-tunes one after the other (a run collects on every core); their exports, configs and curves to
    ``results``."""
    results.mkdir(parents=True, exist_ok=True)
    for preset in PRESETS:
        out, started = work / f"g1_ft_{preset}", time.perf_counter()
        with (work / f"{preset}.log").open("w") as log:
            proc = subprocess.Popen(train_command(preset, out, args.minutes, args.max_steps, args.num_envs),
                                    stdout=log, stderr=subprocess.STDOUT, cwd=REPO)
        if proc.wait() != 0:
            raise SystemExit(f"training {preset} failed: see {work / f'{preset}.log'}")
        for name, target in (("policy.onnx", f"{preset}.onnx"), ("run_config.json", f"{preset}.run_config.json"),
                             ("curve.jsonl", f"{preset}.curve.jsonl")):
            shutil.copy(out / name, results / target)
        print(f"trained {preset}: {time.perf_counter() - started:.0f} s wall", flush=True)


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
            by_policy[row["policy"]] = {"row": row, "episodes": [e.summary for e in reg.episodes(run_ids=[run_id])]}
    return {"wall_s": wall, "summary": result["summary"], "policies": by_policy}


def columns(episodes: list[dict]) -> tuple[np.ndarray, ...]:
    get = lambda key: np.array([float(e[key]) for e in episodes])
    return get("energy_wh"), get("units_completed"), get("episode_length_s") / 3600.0, get("errors")


def wh_per_leg(wh: np.ndarray, legs: np.ndarray, *_: np.ndarray) -> float:
    return float(wh.sum() / legs.sum()) if legs.sum() > 0 else float("inf")


def legs_per_hour(wh: np.ndarray, legs: np.ndarray, hours: np.ndarray, *_: np.ndarray) -> float:
    return float(legs.sum() / hours.sum())


def paired(stat, a: tuple[np.ndarray, ...], b: tuple[np.ndarray, ...], seed: int = 20261128) -> tuple[float, ...]:
    """``stat(a) - stat(b)`` and its 90% bootstrap interval, episodes resampled in pairs (same seeds)."""
    rng = np.random.default_rng(seed)
    n = min(len(a[0]), len(b[0]))
    picks = rng.integers(0, n, size=(RESAMPLES, n))
    values = [stat(*(c[p] for c in a)) - stat(*(c[p] for c in b)) for p in picks]
    return stat(*a) - stat(*b), float(np.quantile(values, 0.05)), float(np.quantile(values, 0.95))


def fall_bound(episodes: list[dict]) -> float:
    from econmotor.economics.uncertainty import clopper_pearson

    _, legs, _, falls = columns(episodes)
    return clopper_pearson(falls.sum(), legs.sum() + falls.sum(), 0.90)[1]


def report(tag: str, cmp: dict, names: dict[str, str]) -> dict:
    print(f"\n{TASK}, {tag}: compare in {cmp['wall_s']:.0f} s")
    print(f"{'policy':<14}{'legs/h':>8}{'Wh/leg':>8}{'falls/legs':>12}{'fall<=90%':>10}{'USD/leg':>9}  verdict")
    out: dict = {"wall_s": cmp["wall_s"], "summary": cmp["summary"], "policies": {}}
    for name, policy in names.items():
        entry = cmp["policies"][policy]
        cols, row = columns(entry["episodes"]), entry["row"]
        figures = {"legs_per_hour": legs_per_hour(*cols), "wh_per_leg": wh_per_leg(*cols),
                   "falls": float(cols[3].sum()),
                   "legs": float(cols[1].sum()), "fall_bound90": fall_bound(entry["episodes"]),
                   "price_usd_per_leg": row["price_usd_per_unit"], "verdict": row["verdict"],
                   "deployable": row["deployable"], "episodes": len(entry["episodes"])}
        out["policies"][name] = figures
        falls = f"{figures['falls']:.0f}/{figures['legs']:.0f}"
        print(f"{name:<14}{figures['legs_per_hour']:>8.1f}{figures['wh_per_leg']:>8.3f}{falls:>12}"
              f"{figures['fall_bound90']:>10.4f}"
              f"{figures['price_usd_per_leg']:>9.4f}  {row['verdict']}")
    eps = {name: columns(cmp["policies"][policy]["episodes"]) for name, policy in names.items()}
    pairs = (("energy_saver", "ppo"), ("throughput", "ppo"), ("energy_saver", "throughput"))
    out["paired"] = {}
    for a, b in pairs:
        wh = paired(wh_per_leg, eps[a], eps[b])
        lph = paired(legs_per_hour, eps[a], eps[b])
        out["paired"][f"{a}-{b}"] = {"wh_per_leg": wh, "legs_per_hour": lph}
        print(f"{a} - {b}, Wh/leg (paired, same seeds): {wh[0]:+.3f}, 90% interval {wh[1]:+.3f} - {wh[2]:+.3f}; "
              f"legs/h {lph[0]:+.1f}, 90% interval {lph[1]:+.1f} - {lph[2]:+.1f}")
    for a in PRESETS:
        diff = out["policies"][a]["fall_bound90"] - out["policies"]["ppo"]["fall_bound90"]
        out["paired"][f"{a}-ppo"]["fall_bound90"] = diff
        print(f"{a} - ppo, 90% upper bound of the fall rate per leg: {diff:+.4f}")
    print(cmp["summary"])
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--train", action="store_true", help="fine-tune both presets first (else: the exports "
                        "in --results)")
    parser.add_argument("--minutes", type=float, default=58.0, help="wall-time budget of each fine-tune")
    parser.add_argument("--max-steps", type=int, default=100_000_000)
    parser.add_argument("--num-envs", type=int, default=None, help="robots per run (default: the catalog's)")
    parser.add_argument("--nominal-episodes", type=int, default=120)
    parser.add_argument("--stress-episodes", type=int, default=60)
    parser.add_argument("--results", type=Path, default=RESULTS, help="where the exports are (and go)")
    args = parser.parse_args()
    work = Path(tempfile.mkdtemp(prefix="g1-objectives-"))
    if args.train:
        train(args, args.results, work)
    names = {p: str((args.results / f"{p}.onnx").resolve()) for p in PRESETS} | SHIPPED
    nominal = report("nominal", compare(names, args.nominal_episodes, False, work), names)
    stressed = report("stress", compare(names, args.stress_episodes, True, work), names)
    (work / "g1_objectives.json").write_text(json.dumps({"nominal": nominal, "stress": stressed}, indent=2))
    print(f"\nfigures in {work / 'g1_objectives.json'}")


if __name__ == "__main__":
    main()
