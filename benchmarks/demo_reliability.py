"""Does the demo's hopper courier pass its acceptance on more than one seed?

Trains ``hopper_courier`` (the demo's objective, ``courier_demo.yaml``; ``--objective-vector`` for
another) for ``--max-steps`` with the
catalog's PPO hyperparameters, optionally overridden by ``--hp '{"learning_rate": 1e-4}'``,
evaluates ``--eval-episodes`` deterministic episodes and prints falls, attempted legs, the 95%
Clopper-Pearson upper bound on the fall rate, legs/h and the accept/reject call against the
task's acceptance (fall-rate upper bound <= max_error_rate, legs/h >= min_units_per_hour).

    PYTHONPATH=src .venv/bin/python benchmarks/demo_reliability.py --seed 0 --out /tmp/rel-s0
"""

from __future__ import annotations

import argparse
import json
import time

from econmotor.cli.demo import DEMO_OBJECTIVE, DEMO_TASK
from econmotor.cli.options import resolve_objective
from econmotor.config.objective_profile import ObjectiveVector
from econmotor.economics.uncertainty import clopper_pearson
from econmotor.motor_backend.factory import make_motor_backend
from econmotor.objectives.loader import objective_from_vector

#: the smallest run (tests/integration/test_benchmarks.py): one PPO iteration of 4 x 16 steps
SMOKE_ARGS: list[str] = ["--max-steps", "64", "--eval-episodes", "1", "--hp", '{"n_steps": 16, "n_epochs": 1}',
                         "--out", "run"]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--max-steps", type=int, default=300_000)
    parser.add_argument("--eval-episodes", type=int, default=80)
    parser.add_argument("--hp", default="{}", help="JSON PPO hyperparameter overrides")
    parser.add_argument("--objective-vector", default=None,
                        help="JSON [mpl, error, energy, safety, novelty] instead of the demo's objective")
    parser.add_argument("--out", required=True, help="run directory")
    args = parser.parse_args()
    backend = make_motor_backend("mujoco")
    if args.objective_vector:
        vector = ObjectiveVector.from_list(json.loads(args.objective_vector))
        objective = objective_from_vector(vector, "probe")
    else:
        objective = resolve_objective(DEMO_OBJECTIVE, None)
    started = time.perf_counter()
    result = backend.train_policy(DEMO_TASK, objective, [], 0, args.max_steps, args.seed, output_dir=args.out,
                                  eval_episodes=args.eval_episodes, hyperparameters=json.loads(args.hp))
    wall_s = time.perf_counter() - started
    eps = result.episodes
    falls = sum(float(e["errors"]) for e in eps)
    legs = sum(float(e["units_completed"]) for e in eps)
    hours = sum(float(e["episode_length_s"]) for e in eps) / 3600.0
    upper = clopper_pearson(falls, legs + falls)[1]
    legs_per_h = legs / hours if hours > 0 else 0.0
    acceptance = backend.catalog.get(DEMO_TASK).acceptance
    ok = upper <= acceptance.max_error_rate and legs_per_h >= acceptance.min_units_per_hour
    print(json.dumps({"seed": args.seed, "objective": objective.name, "hp": json.loads(args.hp),
                      "max_steps": args.max_steps, "episodes": len(eps), "falls": falls, "legs": round(legs, 1),
                      "fall_rate_upper95": round(upper, 4), "legs_per_h": round(legs_per_h, 1),
                      "accept": ok, "wall_s": round(wall_s, 1)}))


if __name__ == "__main__":
    main()
