"""MJX env steps/s with the catalog's ``model_options`` vs Gymnasium's own model, side by side.

Gymnasium's MJCF files are written for MuJoCo C: RK4, 50-100 Newton iterations at tolerance
1e-8 (which float32 never reaches, so a batch runs every iteration), every capsule colliding.
``tasks/mjx.yaml`` runs the couriers as Brax and MuJoCo Playground run these robots on MJX
(Euler, 1-4 solver / 4-8 line-search iterations, feet-only contacts; see ``mjx/assets.py``).
Both arms are the full courier env (economics included) in one process, A B B A rounds of one
jitted ``lax.scan`` each; the ratio is catalog / Gymnasium (how many times faster).

    .venv/bin/python benchmarks/mjx_model_options.py                      # CPU: 32 / 16 envs
    .venv/bin/python benchmarks/mjx_model_options.py --num-envs 2048 --steps 200   # a GPU
"""

from __future__ import annotations

import argparse
import os
from dataclasses import replace

os.environ.setdefault("XLA_FLAGS", "--xla_cpu_multi_thread_eigen=false intra_op_parallelism_threads=1")

from mjx_throughput import side_by_side

#: the smallest run (tests/integration/test_benchmarks.py): the hopper, one env, one step per block
SMOKE_ARGS: list[str] = ["--tasks", "hopper_courier", "--num-envs", "1", "--steps", "1", "--rounds", "1"]


def gymnasium_model_catalog(task_id: str):
    """The catalog with ``task_id``'s mjx entry stripped of its ``model_options``."""
    from econmotor.tasks import load_catalog
    from econmotor.tasks.catalog import TaskCatalog

    spec = load_catalog().get(task_id)
    entry = {k: v for k, v in spec.backends["mjx"].items() if k != "model_options"}
    return TaskCatalog({task_id: replace(spec, backends={**spec.backends, "mjx": entry})})


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--tasks", nargs="*", default=["hopper_courier", "humanoid_courier"])
    parser.add_argument("--num-envs", type=int, default=0, help="0: 32 hopper / 16 humanoid envs on a CPU")
    parser.add_argument("--steps", type=int, default=40, help="env steps per block")
    parser.add_argument("--rounds", type=int, default=3)
    args = parser.parse_args()

    from econmotor.motor_backend.mjx.env import GymCourierEnv
    from econmotor.motor_backend.mjx.wrappers import make_env
    from econmotor.objectives import EconomicObjectiveSpec

    objective = EconomicObjectiveSpec()
    for task_id in args.tasks:
        num_envs = args.num_envs or (16 if "humanoid" in task_id else 32)
        catalog_env = make_env(GymCourierEnv, task_id, objective=objective)
        gymnasium_env = make_env(GymCourierEnv, task_id, objective=objective,
                                 catalog=gymnasium_model_catalog(task_id))
        side_by_side(task_id, catalog_env, gymnasium_env, ("catalog model_options", "Gymnasium's model"),
                     num_envs, args.steps, args.rounds)


if __name__ == "__main__":
    main()
