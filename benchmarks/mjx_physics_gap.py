"""The price of one mjx-trained policy on three physics: how far the fast MJX options move it.

The mjx backend trains and evaluates the couriers on ``tasks/mjx.yaml``'s ``model_options``
(Euler, 1-4 solver iterations, feet-only contacts: what Brax and MuJoCo Playground run, ~12x /
~90x faster than Gymnasium's model in MJX, ``mjx_model_options.py``). A buyer's robot runs the
physics of Gymnasium's model, so the question is how much a price measured on the fast options
moves. One policy, trained here by the mjx backend, is evaluated on the same seeds on:

- ``mjx options``: MJX with the catalog's ``model_options`` (what ``report --motor-backend mjx`` prices);
- ``mjx full``: MJX with Gymnasium's model as written (RK4, 50+ Newton iterations, all contacts), float32;
- ``mujoco C``: the ``mujoco`` backend's evaluation env (MuJoCo C, float64, Gymnasium's model and
  wrappers) driving the run's exported ``policy.onnx`` (the deployable artefact).

Each arm prints legs/h, falls, Wh per leg and cost per unit, and its ratio to ``mjx options``.

    .venv/bin/python benchmarks/mjx_physics_gap.py [--task-id hopper_courier] [--max-steps 1000000]
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

os.environ.setdefault("XLA_FLAGS", "--xla_cpu_multi_thread_eigen=false intra_op_parallelism_threads=1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

from mjx_model_options import gymnasium_model_catalog

#: the smallest run (tests/integration/test_benchmarks.py): 20 env steps on one env, one episode per arm
SMOKE_ARGS: list[str] = ["--max-steps", "20", "--num-envs", "1", "--episodes", "1"]
FIGURES = (("mpl_units_per_hour", "legs/h"), ("error_rate", "error rate"), ("energy_wh_per_unit", "Wh/leg"),
           ("robot_unit_cost_usd", "USD/leg"))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--task-id", default="hopper_courier")
    parser.add_argument("--max-steps", type=int, default=1_000_000, help="env steps the policy trains")
    parser.add_argument("--num-envs", type=int, default=0, help="0: the catalog's (capped on a CPU)")
    parser.add_argument("--episodes", type=int, default=20)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()

    from econmotor.motor_backend.mjx.backend import MjxBackend
    from econmotor.motor_backend.mujoco.backend import MujocoBackend
    from econmotor.motor_backend.mujoco.env_factory import make_env
    from econmotor.motor_backend.mujoco.evaluation import rollout_episodes
    from econmotor.motor_backend.results import evaluation_result
    from econmotor.objectives import EconomicObjectiveSpec
    from econmotor.tasks import load_catalog

    objective = EconomicObjectiveSpec()
    economics = load_catalog().get(args.task_id).economics
    eval_seed = args.seed + 1_000
    with tempfile.TemporaryDirectory() as tmp:
        fast = MjxBackend(runs_dir=tmp, compilation_cache_dir=None)
        start = time.perf_counter()
        trained = fast.train_policy(args.task_id, objective, (), args.num_envs, args.max_steps, args.seed,
                                    output_dir=Path(tmp) / "run", eval_episodes=0)
        print(f"{args.task_id}: trained {args.max_steps:,} env steps on mjx options in "
              f"{time.perf_counter() - start:.0f} s; evaluating {args.episodes} episodes per arm "
              f"(seeds from {eval_seed})")
        policy = trained.policy_id
        arms = {"mjx options": fast.evaluate_policy(policy, args.task_id, objective, args.episodes, eval_seed)}

        full = MjxBackend(runs_dir=tmp, compilation_cache_dir=None)
        full.catalog = gymnasium_model_catalog(args.task_id)
        arms["mjx full"] = full.evaluate_policy(policy, args.task_id, objective, args.episodes, eval_seed)

        mujoco = MujocoBackend(runs_dir=tmp)
        recipe, _ = mujoco.recipe(args.task_id, objective)
        env = make_env(mujoco._eval_recipe(recipe), seed=eval_seed)
        handle = fast.deploy_policy_handle(policy)
        rows = rollout_episodes(env, handle.act, args.episodes, eval_seed)
        env.close()
        arms["mujoco C"] = evaluation_result("mujoco", policy, args.task_id, rows, economics, {})

    base = arms["mjx options"].econ_metrics
    print(f"{'arm':12s} " + " ".join(f"{label:>16s}" for _, label in FIGURES) + f" {'falls':>6s}")
    for name, result in arms.items():
        econ = result.econ_metrics
        falls = econ.get("errors", float("nan"))
        cells = []
        for key, _ in FIGURES:
            value, ref = econ.get(key, float("nan")), base.get(key, float("nan"))
            ratio = f"({value / ref:4.2f})" if ref else "(   -)"
            cells.append(f"{value:9.4g} {ratio}" if name != "mjx options" else f"{value:16.4g}")
        print(f"{name:12s} " + " ".join(f"{c:>16s}" for c in cells) + f" {falls:6.0f}")
    print("(ratio to mjx options in brackets)")


if __name__ == "__main__":
    main()
