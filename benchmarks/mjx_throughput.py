"""MJX throughput, measured side by side in one run.

1. Env steps/s of ``jit(vmap(step))`` with and without the economics inside the step
   (``env_step_throughput``; goal: ratio >= 0.98).
2. PPO training env steps/s of the ``mjx`` backend (JAX PPO, ``num_envs`` batched MJX envs on
   the JAX device) vs the ``mujoco`` backend's Stable-Baselines3 PPO (its catalog num_envs of
   in-process Gymnasium envs on the CPU), same task (hopper_courier), same objective
   (``ppo_vs_sb3``). Each is timed from its first to its last progress report after the first
   report, i.e. without env creation, XLA compilation (mjx: the first iteration) or
   evaluation. Goal on a GPU: ratio >= 100; on 2 CPU cores it is reported as it is.

    .venv/bin/python benchmarks/mjx_throughput.py                   # GPU: catalog num_envs
    .venv/bin/python benchmarks/mjx_throughput.py --mjx-envs 32 --mjx-steps 20000 --sb3-steps 8192  # CPU
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time

os.environ.setdefault("OMP_NUM_THREADS", "1")

TASK = "hopper_courier"


def _timed_progress() -> tuple[list[tuple[float, float]], object]:
    stamps: list[tuple[float, float]] = []

    def progress(label: str, done: float, total: float) -> None:
        if label == "train":
            stamps.append((time.perf_counter(), done))

    return stamps, progress


def _rate(stamps: list[tuple[float, float]]) -> float:
    """Steps/s from the second progress report (after the first iteration: compilation) to the last."""
    (t0, n0), (t1, n1) = stamps[1], stamps[-1]
    return (n1 - n0) / (t1 - t0) if t1 > t0 else float("nan")


def mjx_ppo_throughput(steps: int, num_envs: int, seed: int = 0) -> tuple[float, int, str]:
    """(env steps/s, num_envs used, device) of ``MjxBackend.train_policy`` after compilation."""
    from econmotor.motor_backend.mjx.backend import MjxBackend, device_description
    from econmotor.objectives import EconomicObjectiveSpec

    backend = MjxBackend()
    stamps, progress = _timed_progress()
    with tempfile.TemporaryDirectory() as out:
        result = backend.train_policy(TASK, EconomicObjectiveSpec(), [], num_envs, steps, seed, output_dir=out,
                                      eval_episodes=0, progress=progress)
    return _rate(stamps), int(result.config["num_envs"]), device_description()


def sb3_ppo_throughput(steps: int, seed: int = 0) -> tuple[float, int]:
    """(env steps/s, num_envs) of the mujoco backend's SB3 PPO (catalog num_envs, CPU)."""
    import torch

    from econmotor.motor_backend.mujoco_backend import MujocoBackend
    from econmotor.objectives import EconomicObjectiveSpec

    torch.set_num_threads(1)
    backend = MujocoBackend()
    stamps, progress = _timed_progress()
    with tempfile.TemporaryDirectory() as out:
        result = backend.train_policy(TASK, EconomicObjectiveSpec(), [], 0, steps, seed, output_dir=out,
                                      eval_episodes=0, progress=progress, algorithm="ppo")
    return _rate(stamps), int(result.config["num_envs"])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--mjx-envs", type=int, default=0, help="0: the catalog's (capped on a CPU)")
    parser.add_argument("--mjx-steps", type=int, default=20_000_000)
    parser.add_argument("--sb3-steps", type=int, default=20_480)
    parser.add_argument("--skip-env-step", action="store_true", help="only the PPO comparison")
    args = parser.parse_args()
    env_step = globals().get("env_step_throughput")
    if env_step is not None and not args.skip_env_step:
        env_step()
    sb3, sb3_envs = sb3_ppo_throughput(args.sb3_steps)
    print(f"mujoco backend, SB3 PPO, {sb3_envs} CPU envs: {sb3:10,.0f} env steps/s", flush=True)
    mjx, mjx_envs, device = mjx_ppo_throughput(args.mjx_steps, args.mjx_envs)
    print(f"mjx backend, JAX PPO, {mjx_envs} envs on {device}: {mjx:10,.0f} env steps/s", flush=True)
    print(f"PPO training throughput ratio mjx / mujoco (SB3): {mjx / sb3:.2f}x "
          f"(goal on a GPU: >= 100x)")


if __name__ == "__main__":
    main()
