"""MJX G1 (or T1) courier env steps/s with and without the economics in the step, side by side.

"With": the batched ``HumanoidWalkerEnv`` as the mjx backend trains on it (metering every physics step,
the overlay of the default objective vector); "without": the same env built with
``economics=False`` (physics, PD loop, course, observation, locomotion reward, auto-reset only).
Blocks of one jitted ``lax.scan`` run in A B B A rounds (``mjx_throughput.side_by_side``); the
ratio is the median round's, with the range. Actions are drawn uniformly in [-1, 1] (a policy's
range: +-action_clip would topple the robot every step).

    .venv/bin/python benchmarks/mjx_humanoid_throughput.py                     # GPU: catalog num_envs
    .venv/bin/python benchmarks/mjx_humanoid_throughput.py --envs 4 --steps 10 --rounds 3   # CPU
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("XLA_FLAGS", "--xla_cpu_multi_thread_eigen=false intra_op_parallelism_threads=1")
sys.path.insert(0, str(Path(__file__).parent))

from mjx_throughput import side_by_side

#: the smallest run (tests/integration/test_benchmarks.py)
SMOKE_ARGS: list[str] = ["--envs", "1", "--steps", "1", "--rounds", "1"]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--task", default="humanoid_locomotion_g1")
    parser.add_argument("--envs", type=int, default=0, help="0: the catalog's (capped on a CPU)")
    parser.add_argument("--steps", type=int, default=0, help="control steps per block (0: 1000 GPU, 20 CPU)")
    parser.add_argument("--rounds", type=int, default=5)
    args = parser.parse_args()

    import numpy as np

    from econmotor.config.objective_profile import ObjectiveVector
    from econmotor.motor_backend.mjx.humanoid_env import HumanoidWalkerEnv
    from econmotor.motor_backend.mjx.wrappers import make_env
    from econmotor.objectives.loader import objective_from_vector
    from econmotor.valuation import default_objective_vector

    objective = objective_from_vector(ObjectiveVector.from_list(default_objective_vector()), "default")
    envs = [make_env(HumanoidWalkerEnv, args.task, objective=objective, economics=e) for e in (True, False)]
    for env in envs:
        env.action_low, env.action_high = -np.ones(env.action_size, np.float32), np.ones(env.action_size, np.float32)
    side_by_side(args.task, *envs, ("with economics", "without"), args.envs, args.steps, args.rounds,
                 goal="goal >= 0.98")


if __name__ == "__main__":
    main()
