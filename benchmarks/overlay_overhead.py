"""Steps/s of the metered + overlay MuJoCo env over the raw Gymnasium env, same run.

Both envs step the same pre-drawn random actions (resetting on episode end); timing
alternates in short blocks (raw, wrapped, raw, wrapped, ...) so machine load hits both alike.
Reported: steps/s of the median blocks, the median over rounds of the paired ratio
(raw block time / the wrapped block right after it: pairs see the same load, so this is
the robust number on a shared machine) and the ratio of the fastest blocks (as ``timeit``).
The wrapped env is what the mujoco backend trains on: EconomicMeteringWrapper +
EconomicOverlayWrapper with the default objective vector's overlay, human-baseline
normalised. Goal: ratio >= 0.95.

    .venv/bin/python benchmarks/overlay_overhead.py [--steps 20000] [--rounds 5]
"""

from __future__ import annotations

import argparse
import time

import gymnasium as gym
import numpy as np

from econmotor.config.objective_profile import ObjectiveVector
from econmotor.motor_backend.mujoco.env_factory import make_env
from econmotor.motor_backend.mujoco_backend import MujocoBackend
from econmotor.objectives.loader import objective_from_vector
from econmotor.valuation import default_objective_vector

TASKS = {"hopper_courier": "Hopper-v5", "humanoid_courier": "Humanoid-v5"}


def time_block(env: gym.Env, actions: np.ndarray) -> float:
    """Seconds to step ``actions`` through ``env`` (resets on episode end included)."""
    start = time.perf_counter()
    for action in actions:
        _, _, terminated, truncated, _ = env.step(action)
        if terminated or truncated:
            env.reset()
    return time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=1_000, help="steps per block")
    parser.add_argument("--rounds", type=int, default=50, help="alternating blocks per env")
    args = parser.parse_args()
    backend = MujocoBackend()
    objective = objective_from_vector(ObjectiveVector.from_list(default_objective_vector()), "default")
    print(f"{'task':18s} {'raw steps/s':>12s} {'wrapped steps/s':>16s} {'ratio (paired)':>15s} "
          f"{'ratio (fastest)':>16s}")
    for task_id, env_id in TASKS.items():
        recipe, _ = backend.recipe(task_id, objective)
        raw_env, wrapped = gym.make(env_id), make_env(recipe, seed=0)
        raw_env.reset(seed=0)
        wrapped.reset(seed=0)
        actions = np.random.default_rng(0).uniform(-0.4, 0.4, size=(args.steps, *raw_env.action_space.shape))
        time_block(raw_env, actions[:1000])  # warm up both
        time_block(wrapped, actions[:1000])
        raw_s, wrapped_s = [], []
        for _ in range(args.rounds):
            raw_s.append(time_block(raw_env, actions))
            wrapped_s.append(time_block(wrapped, actions))
        raw_med, wrapped_med = float(np.median(raw_s)), float(np.median(wrapped_s))
        paired = float(np.median([r / w for r, w in zip(raw_s, wrapped_s, strict=True)]))
        print(f"{task_id:18s} {args.steps / raw_med:12.0f} {args.steps / wrapped_med:16.0f} "
              f"{paired:15.3f} {min(raw_s) / min(wrapped_s):16.3f}")


if __name__ == "__main__":
    main()
