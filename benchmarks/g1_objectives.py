"""Do objectives move a real robot? The G1 fine-tuned from Holosoma's shipped PPO walker under two objectives.

Same start, different economics: two mjx runs of ``humanoid_locomotion_g1`` start from
``holosoma:g1_29dof/ppo`` (``--init-policy``: the walker's actor, a critic warm-up, then PPO) with
the same seed and steps, one under the ``throughput`` preset and one under ``energy_saver``. Each
exported ``policy.onnx`` (Holosoma's format) and the shipped walker itself then walk the same
sim-to-sim course (the holosoma backend's evaluator, ``.venv-holosoma``) on the same seeds under the
stress datapack (floor friction, payload, shoves: the episodes differ beyond their start pose).

Printed per policy: legs/h, Wh per leg (the meter's energy / legs completed) with a 90% bootstrap
interval over episodes, falls; then the paired difference energy_saver - throughput in Wh per leg
(episode i of both on the same seed, resampled together), with its 90% interval. The ordering the
objectives ask for is energy_saver's Wh per leg below throughput's; it is shown when the paired
interval lies below 0.

Run: ``OMP_NUM_THREADS=1 .venv/bin/python benchmarks/g1_objectives.py [--steps 20000] [--episodes 20]``;
``--onnx throughput=runs/a/policy.onnx --onnx energy_saver=runs/b/policy.onnx`` prices two runs already
trained (``econmotor train ... --init-policy holosoma:g1_29dof/ppo --objective-preset <preset>``).
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

from econmotor.config.objective_profile import ObjectiveVector
from econmotor.motor_backend.datapacks import load_datapack_configs
from econmotor.motor_backend.holosoma.host.backend import HolosomaBackend
from econmotor.motor_backend.mjx.backend import MjxBackend
from econmotor.objectives import EconomicObjectiveSpec, objective_from_vector

TASK = "humanoid_locomotion_g1"
SHIPPED = "holosoma:g1_29dof/ppo"
PRESETS = ("throughput", "energy_saver")
STRESS = Path(__file__).resolve().parents[1] / "configs" / "datapacks" / "humanoid_stress.yaml"
EVAL_SEED = 700_000
RESAMPLES = 2000


#: the smallest run: one PPO iteration of 1 env x 20 steps (tests/integration/test_benchmarks.py)
SMOKE_ARGS: list[str] = ["--steps", "20", "--num-envs", "1", "--episodes", "1"]


def wh_per_leg(wh: np.ndarray, legs: np.ndarray) -> float:
    return float(wh.sum() / legs.sum()) if legs.sum() > 0 else float("inf")


def interval(stat, *columns: np.ndarray, seed: int = 20240601) -> tuple[float, float]:
    """5% and 95% quantiles of ``stat`` over episodes resampled with replacement (rows kept together)."""
    rng = np.random.default_rng(seed)
    n = len(columns[0])
    values = [stat(*(c[pick] for c in columns)) for pick in rng.integers(0, n, size=(RESAMPLES, n))]
    return float(np.quantile(values, 0.05)), float(np.quantile(values, 0.95))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=20_000, help="env steps per fine-tuning run")
    parser.add_argument("--episodes", type=int, default=20, help="sim-to-sim episodes per policy")
    parser.add_argument("--num-envs", type=int, default=16)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--onnx", action="append", default=[], metavar="PRESET=PATH",
                        help="a trained run's policy.onnx for a preset (no training for it)")
    args = parser.parse_args()
    out = Path(tempfile.mkdtemp(prefix="g1-objectives-"))
    policies: dict[str, str] = dict(item.split("=", 1) for item in args.onnx)
    mjx = MjxBackend(runs_dir=out)
    for preset in (p for p in PRESETS if p not in policies):
        started = time.perf_counter()
        objective = objective_from_vector(ObjectiveVector.from_preset(preset), name=preset)
        result = mjx.train_policy(TASK, objective, [], args.num_envs, args.steps, args.seed, output_dir=out / preset,
                                  eval_episodes=0, select_every_steps=0, init_policy=SHIPPED)
        timing = result.config["timing"]
        print(f"{preset}: {timing['total_steps']:,} env steps in {time.perf_counter() - started:.0f} s "
              f"(first iteration {timing['first_iteration_s']:.0f} s, then "
              f"{timing['env_steps_per_s_after_compile'] or 0:,.0f} steps/s)", flush=True)
        policies[preset] = result.artifacts["onnx"]
    policies["shipped"] = SHIPPED
    holosoma = HolosomaBackend(runs_dir=out)
    stress = load_datapack_configs([STRESS])
    rows = {}
    for name, policy in policies.items():
        started = time.perf_counter()
        ev = holosoma.evaluate_policy(policy, TASK, EconomicObjectiveSpec(), args.episodes, EVAL_SEED,
                                      datapack_configs=stress, output_dir=out / f"eval-{name}")
        wh = np.array([e["energy_wh"] for e in ev.episodes])
        legs = np.array([e["units_completed"] for e in ev.episodes])
        hours = np.array([e["episode_length_s"] for e in ev.episodes]) / 3600.0
        rows[name] = (wh, legs, hours, sum(e["errors"] for e in ev.episodes))
        print(f"evaluated {name} ({args.episodes} episodes, {time.perf_counter() - started:.0f} s)", flush=True)
    print(f"\n{TASK}: fine-tuned from {SHIPPED} ({args.steps:,} env steps, seed {args.seed}, unless --onnx); "
          f"{args.episodes} sim-to-sim episodes each, seeds {EVAL_SEED}-{EVAL_SEED + args.episodes - 1}, "
          f"datapack {STRESS.stem}")
    print(f"{'policy':<14}{'legs/h':>9}{'Wh/leg':>9}{'90% interval':>18}{'falls':>7}")
    for name, (wh, legs, hours, falls) in rows.items():
        low, high = interval(wh_per_leg, wh, legs)
        print(f"{name:<14}{legs.sum() / hours.sum():>9.1f}{wh_per_leg(wh, legs):>9.2f}"
              f"{f'{low:.2f} - {high:.2f}':>18}{falls:>7.0f}")
    (wh_t, legs_t, _, _), (wh_e, legs_e, _, _) = rows["throughput"], rows["energy_saver"]
    diff = wh_per_leg(wh_e, legs_e) - wh_per_leg(wh_t, legs_t)
    low, high = interval(lambda a, b, c, d: wh_per_leg(a, b) - wh_per_leg(c, d), wh_e, legs_e, wh_t, legs_t)
    verdict = "shown" if high < 0 else ("reversed" if low > 0 else "NOT shown (the interval contains 0)")
    print(f"energy_saver - throughput, Wh/leg (paired, same seeds): {diff:+.3f}, 90% interval "
          f"{low:+.3f} - {high:+.3f}: the ordering the objectives ask for is {verdict}")
    print(f"runs and evaluations in {out}")


if __name__ == "__main__":
    main()
