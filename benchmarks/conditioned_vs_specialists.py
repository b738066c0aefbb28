"""One dirichlet-conditioned SAC policy vs one specialist per preset, equal total steps.

Specialists train ``--steps`` each on ``throughput``, ``energy_saver`` and ``safety``
(fixed objective); the conditioned policy trains ``3 * --steps`` with a fresh
Dirichlet(1,1,1,1,0) vector per episode in its observation. All learners see the
RewardBuilder reward (flipped) with dollar-consistent (``analytic``) weights, on the
same workcell as benchmarks/constraints_dishwashing.py. Each policy is evaluated
deterministically under each preset, pinned in the observation. Printed per preset:

- return: the episode sum of the trained per-step objective reward (analytic weights;
  the step terms are increments summing to the episode's, so this is the analytic
  scalarisation of the episode summary);
- J: ``combine_reward(normalised preset, build_reward_terms(episode summary))`` (spec form);
- the conditioned policy's ratio to the specialist on both (goal: >= 0.90).

    .venv/bin/python benchmarks/conditioned_vs_specialists.py [--steps 4000] [--seed 0]
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")
sys.path.insert(0, str(Path(__file__).resolve().parent))

import torch
from constraints_dishwashing import FAST_SAC, WORKCELL

from econmotor.config.objective_profile import OBJECTIVE_PRESETS
from econmotor.rl.train_sac_objective import ShadowConfig, train_sac_objective

PRESETS = ("throughput", "energy_saver", "safety")
#: the smallest run (tests/integration/test_benchmarks.py): one 60-step episode per specialist, no gradient step
SMOKE_ARGS: list[str] = ["--steps", "60", "--eval-episodes", "1"]


def train(label: str, sampling: str, steps: int, seed: int, eval_episodes: int) -> dict:
    vector = OBJECTIVE_PRESETS[label] if label in OBJECTIVE_PRESETS else OBJECTIVE_PRESETS["balanced"]
    evals = {label: vector} if sampling == "fixed" else {p: OBJECTIVE_PRESETS[p] for p in PRESETS}
    config = ShadowConfig(env="dishwashing", objective=vector, objective_label=label, total_steps=steps,
                          use_objective_reward=True, reward_weights="analytic", objective_sampling=sampling,
                          seed=seed, eval_episodes=eval_episodes, eval_objectives=evals, **WORKCELL, **FAST_SAC)
    return train_sac_objective(config).evaluation


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=4000, help="steps per specialist")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--eval-episodes", type=int, default=20)
    args = parser.parse_args()
    torch.set_num_threads(1)
    specialists = {p: train(p, "fixed", args.steps, args.seed, args.eval_episodes)[p] for p in PRESETS}
    conditioned = train("dirichlet", "dirichlet", 3 * args.steps, args.seed, args.eval_episodes)
    print(f"{'preset':13s} {'spec return':>11s} {'cond return':>11s} {'ratio':>6s} {'spec J':>8s} {'cond J':>8s} "
          f"{'ratio':>6s}  spec/cond MPL, error rate")
    ratios_return, ratios_j = [], []
    for p in PRESETS:
        s, c = specialists[p], conditioned[p]
        r_ret, r_j = c["objective_sum"] / s["objective_sum"], c["J"] / s["J"]
        ratios_return.append(r_ret)
        ratios_j.append(r_j)
        print(f"{p:13s} {s['objective_sum']:11.3f} {c['objective_sum']:11.3f} {r_ret:6.3f} {s['J']:8.2f} "
              f"{c['J']:8.2f} {r_j:6.3f}  {s['mpl_units_per_hour']:.1f}/{c['mpl_units_per_hour']:.1f}, "
              f"{s['error_rate']:.3f}/{c['error_rate']:.3f}")
    print(f"conditioned / specialist: return ratio min {min(ratios_return):.3f} mean "
          f"{sum(ratios_return) / 3:.3f}; J ratio min {min(ratios_j):.3f} mean {sum(ratios_j) / 3:.3f} "
          f"(goal >= 0.90; {3 * args.steps} conditioned steps = {len(PRESETS)} x {args.steps} specialist steps)")


if __name__ == "__main__":
    main()
