"""Do objective presets train different dishwashing policies? (spec: RewardBuilder integration §7, check 2)

Trains SB3 SAC with the ``dishwashing`` backend under the ``throughput``, ``energy_saver``
and ``safety`` presets (3 seeds each), evaluates every policy on the same evaluation
seeds, adds a uniform-random policy, and prints per preset: MPL (good units/h), Wh per
good unit, error rate (errors / attempts), energy per hour (Wh/h), the mean action and
how episodes ended. Then the ratios the spec expects, measured side by side:

- throughput MPL / max(other presets' MPL)            expected > 1
- safety error rate / min(other presets' error rate)   expected < 1
- energy_saver Wh/h / min(other presets' Wh/h)         expected < 1

Reward scaling: the backend's default ``human_baseline`` normalisation (see
``econmotor.motor_backend.dishwashing.backend``): each metric is divided by what a robot at
the human pace scores (60 units/h, 5 % errors, 3.2 Wh/h) and energy is priced per hour
worked, so a preset's weights compare like with like. Raw terms would make the MPL term
~1,000x the error term and every preset the same.

It also prints each preset's analytic optimum: the constant (speed, care) that maximises the
expected normalised overlay per hour from the model's formulas (a 101 x 101 grid; risk is left
out, it is ~0 at every optimum). Under the spec's presets ``energy_saver`` and ``safety`` share
the same optimum (speed 0, care 1: error rate at ``p_min``, the fewest attempts per hour), so
between those two the error-rate and energy orderings the spec expects are ties at the
optimum and what a finite SAC run shows there is convergence noise.

Run: ``OMP_NUM_THREADS=1 .venv/bin/python benchmarks/preset_differentiation.py [--steps 60000]``
(about 11 minutes on an idle core; the random policy's "speed, care" column is its mean, 0.5).
Measured: at 20,000 steps per run the energy_saver and safety policies had not left the middle
of the action box (Wh/h ratio 1.028, one throughput seed at speed 0.31); at 60,000 throughput
has the highest MPL (1.136), energy_saver the lowest Wh/h (0.919) and safety's error rate ties
the lowest (1.006: every preset sits at the p_min floor, 0.021 +- 0.001). Re-run after the
RewardBuilder energy term became Wh everywhere (the training overlay is unchanged by that),
``--seeds 1`` on a loaded machine (1,640 s): throughput MPL ratio 1.075, safety error-rate
ratio 0.879, energy_saver Wh/h ratio 0.884 (MPL 92.2 / 75.6 / 85.8, Wh/h 4.71 / 3.86 / 4.37).
``--seeds 3`` on one core, the other running the tests (2,231 s; the catalog's 1.67 Wh per
attempt): throughput MPL ratio 1.136, safety error-rate ratio 1.006, energy_saver Wh/h ratio
0.919 (MPL 93.9 / 76.0 / 82.7, Wh/h 160.2 / 129.7 / 141.0 for throughput / energy_saver /
safety). Per seed, the MPL and Wh/h orderings held on all three seeds (MPL 1.195 / 1.113 /
1.102, Wh/h 0.969 / 0.849 / 0.948) and the error-rate ordering on seed 1 only (1.038 / 0.942 /
1.057: every policy sits at the p_min floor, 0.020-0.022). The random row used the env's
default 0.05 Wh per attempt until this run; it now uses the task's parameters.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from collections import Counter
from pathlib import Path

import numpy as np

from econmotor.config.objective_profile import ObjectiveVector
from econmotor.envs import DishwashingEnv
from econmotor.envs.dishwashing import error_probability, expected_attempts_per_step
from econmotor.motor_backend import make_motor_backend, summarize_episodes
from econmotor.motor_backend.dishwashing.backend import DishwashingBackend, term_references
from econmotor.objectives import objective_from_vector
from econmotor.tasks import get_task

PRESETS = ("throughput", "energy_saver", "safety")
EVAL_SEED = 900_000
#: the smallest run (tests/integration/test_benchmarks.py): no gradient step (SAC starts learning later)
SMOKE_ARGS: list[str] = ["--steps", "60", "--num-envs", "1", "--seeds", "1", "--eval-episodes", "1"]


def policy_row(backend: DishwashingBackend, policy_id: str, task_id: str, objective, episodes: int) -> dict:
    """Evaluate a saved policy on the common evaluation seeds; add its mean action (5 episodes)."""
    result = backend.evaluate_policy(policy_id, task_id, objective, episodes, EVAL_SEED)
    handle = backend.deploy_policy_handle(policy_id)
    env = task_env(backend, task_id)
    actions = []
    for i in range(5):
        obs, _ = env.reset(seed=EVAL_SEED + i)
        done = False
        while not done:
            action = handle.act(obs)
            actions.append(action)
            obs, _, term, trunc, _ = env.step(action)
            done = term or trunc
    return row_of(result.econ_metrics, result.episodes, np.mean(actions, axis=0))


def task_env(backend: DishwashingBackend, task_id: str) -> DishwashingEnv:
    """The task's environment as the backend builds it (the catalog's parameters: e.g. 1.67 Wh per attempt)."""
    _, params, _ = backend._task(task_id)
    return DishwashingEnv(params)


def random_row(backend: DishwashingBackend, task_id: str, episodes: int, seed: int) -> dict:
    """A uniform-random (speed, care) policy on the same evaluation seeds and the task's parameters."""
    spec = get_task(task_id)
    env = task_env(backend, task_id)
    rng = np.random.default_rng(seed)
    raw = []
    for i in range(episodes):
        env.reset(seed=EVAL_SEED + i)
        done = False
        while not done:
            _, _, term, trunc, info = env.step(rng.uniform(0, 1, 2).astype(np.float32))
            done = term or trunc
        raw.append(info["episode_summary"])
    _, econ, summaries = summarize_episodes(raw, spec.economics)
    return row_of(econ, summaries, np.array([0.5, 0.5]))


def analytic_optimum(task_id: str, preset: str, grid: int = 101) -> dict:
    """The constant action maximising the expected normalised overlay per hour (see the docstring)."""
    spec, params, _ = DishwashingBackend()._task(task_id)
    refs = term_references(params, spec.economics)
    w = ObjectiveVector.from_preset(preset).to_list()
    steps_per_h = 3600.0 / params.time_step_s
    best: dict = {}
    for speed in np.linspace(0.0, 1.0, grid):
        for care in np.linspace(0.0, 1.0, grid):
            attempts_h = expected_attempts_per_step(params, speed, care) * steps_per_h
            p_err = error_probability(params, speed, care)
            mpl, wh_h = attempts_h * (1.0 - p_err), attempts_h * params.energy_Wh_per_attempt
            j = (w[0] * mpl / refs["mpl_per_hour"] - w[1] * p_err / refs["error_rate"]
                 - w[2] * wh_h / 1000.0 / refs["energy_kwh_per_hour"])
            if not best or j > best["J"]:
                best = {"J": float(j), "speed": float(speed), "care": float(care), "mpl": float(mpl),
                        "error_rate": p_err, "wh_per_hour": float(wh_h)}
    return best


def row_of(econ: dict, episodes: list[dict], mean_action: np.ndarray) -> dict:
    return {
        "mpl": econ["mpl_units_per_hour"],
        "wh_per_unit": econ["energy_wh_per_unit"],
        "error_rate": econ["error_rate"],
        "wh_per_hour": econ["energy_kwh_per_hour"] * 1000.0,
        "speed": float(mean_action[0]),
        "care": float(mean_action[1]),
        "ends": Counter(ep["termination_reason"] for ep in episodes),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--task", default="dishwashing")
    parser.add_argument("--steps", type=int, default=60_000, help="SAC environment steps per run")
    parser.add_argument("--num-envs", type=int, default=4)
    parser.add_argument("--seeds", type=int, default=3)
    parser.add_argument("--eval-episodes", type=int, default=30)
    args = parser.parse_args()

    backend = DishwashingBackend()
    assert isinstance(make_motor_backend("dishwashing"), DishwashingBackend)
    rows: dict[str, list[dict]] = {}
    started = time.perf_counter()
    with tempfile.TemporaryDirectory() as out:
        for preset in PRESETS:
            objective = objective_from_vector(ObjectiveVector.from_preset(preset), preset)
            for seed in range(args.seeds):
                t0 = time.perf_counter()
                result = backend.train_policy(args.task, objective, [], args.num_envs, args.steps, seed,
                                              output_dir=Path(out) / f"{preset}-s{seed}", eval_episodes=1)
                row = policy_row(backend, result.policy_id, args.task, objective, args.eval_episodes)
                rows.setdefault(preset, []).append(row)
                print(f"  {preset:<12} seed {seed}: MPL {row['mpl']:6.1f}  err {row['error_rate']:.4f}  "
                      f"Wh/h {row['wh_per_hour']:.3f}  action ({row['speed']:.2f}, {row['care']:.2f})  "
                      f"[{time.perf_counter() - t0:.0f} s]", flush=True)
    rows["random"] = [random_row(backend, args.task, args.eval_episodes, s) for s in range(args.seeds)]
    total_s = time.perf_counter() - started

    print(f"\nPreset differentiation on '{args.task}': SAC {args.steps} steps on {args.num_envs} envs "
          f"x {args.seeds} seeds per preset, "
          f"{args.eval_episodes} deterministic evaluation episodes per policy (same seeds), {total_s:.0f} s\n")
    header = (f"{'preset':<13}{'MPL units/h':>16}{'Wh/unit':>16}{'error rate':>18}{'Wh/h':>14}"
              f"{'speed, care':>14}   episode ends")
    print(header)
    print("-" * len(header))
    means: dict[str, dict[str, float]] = {}
    for name, rs in rows.items():
        m = {k: float(np.mean([r[k] for r in rs])) for k in ("mpl", "wh_per_unit", "error_rate", "wh_per_hour",
                                                              "speed", "care")}
        s = {k: float(np.std([r[k] for r in rs])) for k in m}
        means[name] = m
        ends = sum((r["ends"] for r in rs), Counter())
        print(f"{name:<13}{m['mpl']:>9.1f} ±{s['mpl']:>5.1f}{m['wh_per_unit']:>9.4f} ±{s['wh_per_unit']:.4f}"
              f"{m['error_rate']:>11.4f} ±{s['error_rate']:.4f}{m['wh_per_hour']:>8.3f} ±{s['wh_per_hour']:.2f}"
              f"   ({m['speed']:.2f}, {m['care']:.2f})   {dict(ends)}")

    print("\nAnalytic optimum per preset (constant action, expected values, normalised overlay):")
    for preset in PRESETS:
        o = analytic_optimum(args.task, preset)
        print(f"  {preset:<13} speed {o['speed']:.2f} care {o['care']:.2f}   MPL {o['mpl']:6.1f}   "
              f"error rate {o['error_rate']:.4f}   Wh/h {o['wh_per_hour']:.3f}")

    def others(name: str, key: str) -> list[float]:
        return [means[p][key] for p in PRESETS if p != name]

    print("\nRatios (expected by the spec):")
    print(f"  throughput MPL / best other preset MPL        = "
          f"{means['throughput']['mpl'] / max(others('throughput', 'mpl')):.3f}   (expected > 1)")
    print(f"  safety error rate / lowest other error rate   = "
          f"{means['safety']['error_rate'] / min(others('safety', 'error_rate')):.3f}   (expected < 1)")
    print(f"  energy_saver Wh/h / lowest other Wh/h         = "
          f"{means['energy_saver']['wh_per_hour'] / min(others('energy_saver', 'wh_per_hour')):.3f}   "
          f"(expected < 1)")
    print(f"  best preset MPL / random policy MPL           = "
          f"{max(means[p]['mpl'] for p in PRESETS) / means['random']['mpl']:.3f}")

    print("\nPer seed (the same three ratios, each seed's policies alone; > 1, < 1, < 1 expected):")
    for seed in range(args.seeds):
        row = {p: rows[p][seed] for p in PRESETS}
        mpl = row["throughput"]["mpl"] / max(row[p]["mpl"] for p in PRESETS if p != "throughput")
        err = row["safety"]["error_rate"] / min(row[p]["error_rate"] for p in PRESETS if p != "safety")
        whh = row["energy_saver"]["wh_per_hour"] / min(row[p]["wh_per_hour"] for p in PRESETS if p != "energy_saver")
        print(f"  seed {seed}: throughput MPL {mpl:.3f}   safety error rate {err:.3f}   energy_saver Wh/h {whh:.3f}")


if __name__ == "__main__":
    main()
