"""Env steps/s of the mujoco backend's training over plain Stable-Baselines3, same run.

Same algorithm, env (Hopper-v5), number of in-process envs, observation normalisation and
hyperparameters (the hopper_courier catalog entry's). Plain SB3: ``DummyVecEnv`` of
``Monitor(gym.make("Hopper-v5"))`` + ``VecNormalize`` + ``model.learn``. Backend:
``MujocoBackend.train_policy`` (metering + overlay wrappers, progress, curve, checkpoint,
TensorBoard and econ-logging callbacks; no held-out evaluations, ``select_every_steps=0``: plain
SB3 runs none), timed from its first to its last progress report (env creation, evaluation and
ONNX export excluded). Runs alternate: plain, backend, ... Goal: ratio >= 0.95. ``--hp`` overrides
the catalog's hyperparameters in both arms (e.g. ``'{"n_steps": 256}'``).

    .venv/bin/python benchmarks/training_throughput.py [--algorithm ppo] [--steps 20480] [--rounds 2] [--hp '{}']
"""

from __future__ import annotations

import argparse
import json
import os
import tempfile
import time

os.environ.setdefault("OMP_NUM_THREADS", "1")

import gymnasium as gym
import torch
from stable_baselines3.common.monitor import Monitor
from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

from econmotor.motor_backend.mujoco.backend import MujocoBackend
from econmotor.motor_backend.mujoco.settings import merge_hyperparameters
from econmotor.motor_backend.mujoco.training import algorithm_class, policy_kwargs_from
from econmotor.motor_backend.sb3_callbacks import quiet_logger
from econmotor.objectives import EconomicObjectiveSpec

TASK = "hopper_courier"
#: the smallest run (tests/integration/test_benchmarks.py): one PPO iteration of 4 x 16 steps per arm
SMOKE_ARGS: list[str] = ["--steps", "64", "--rounds", "1", "--hp", '{"n_steps": 16, "n_epochs": 1}']


def plain_sb3(algorithm: str, hp: dict, num_envs: int, steps: int, seed: int, normalize: bool) -> float:
    venv = DummyVecEnv([lambda: Monitor(gym.make("Hopper-v5")) for _ in range(num_envs)])
    venv.seed(seed)
    if normalize:
        venv = VecNormalize(venv, norm_obs=True, norm_reward=False, clip_obs=10.0)
    model = algorithm_class(algorithm)("MlpPolicy", venv, seed=seed, device="cpu", verbose=0,
                                       **policy_kwargs_from(hp))
    model.set_logger(quiet_logger())  # (SB3's default makes a temp folder at every learn)
    start = time.perf_counter()
    model.learn(steps)
    return model.num_timesteps / (time.perf_counter() - start)


def backend_run(algorithm: str, hp: dict, num_envs: int, steps: int, seed: int) -> float:
    stamps: list[tuple[float, float]] = []

    def progress(label: str, done: float, total: float) -> None:
        if label == "train":
            stamps.append((time.perf_counter(), done))

    with tempfile.TemporaryDirectory() as out:
        MujocoBackend().train_policy(TASK, EconomicObjectiveSpec(), [], num_envs, steps, seed, output_dir=out,
                                     eval_episodes=0, progress=progress, algorithm=algorithm, hyperparameters=hp,
                                     select_every_steps=0)
    (t0, n0), (t1, n1) = stamps[0], stamps[-1]
    return (n1 - n0) / (t1 - t0)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--algorithm", default="ppo", choices=["ppo", "sac"])
    parser.add_argument("--steps", type=int, default=20_480)
    parser.add_argument("--rounds", type=int, default=2)
    parser.add_argument("--hp", default="{}", help="JSON overrides of the catalog's hyperparameters (both arms)")
    args = parser.parse_args()
    torch.set_num_threads(1)
    _, settings = MujocoBackend().task(TASK)
    hp = merge_hyperparameters(settings.algo_hyperparameters(args.algorithm), json.loads(args.hp))
    num_envs = settings.num_envs if args.algorithm == "ppo" else 1
    if args.algorithm == "sac":
        hp.update(buffer_size=max(args.steps, 1000), learning_starts=min(hp.get("learning_starts", 100), 1000))
    plain, ours = [], []
    for r in range(args.rounds):
        plain.append(plain_sb3(args.algorithm, hp, num_envs, args.steps, r, settings.normalize_obs))
        ours.append(backend_run(args.algorithm, hp, num_envs, args.steps, r))
        print(f"round {r}: plain SB3 {plain[-1]:7.0f} steps/s   backend {ours[-1]:7.0f} steps/s")
    p, o = sum(plain) / len(plain), sum(ours) / len(ours)
    print(f"{args.algorithm} x{num_envs} envs, {args.steps} steps x {args.rounds} rounds: "
          f"plain SB3 {p:.0f} steps/s, backend {o:.0f} steps/s, ratio {o / p:.3f}")


if __name__ == "__main__":
    main()
