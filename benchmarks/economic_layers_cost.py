"""Wall time of PPO training runs with and without the economic layers, side by side in one process.

What a user feels: the cost of the economic layers inside a whole Stable-Baselines3 PPO run, not
per env step. The layers are the metering + overlay wrapper (``EconomicMeteringWrapper``, what
the mujoco backend trains on) and the callback that logs their episode figures
(``EconEpisodeLogCallback``). Every arm is one PPO run on the hopper_courier catalog entry's env,
envs, hyperparameters and observation normalisation (``DummyVecEnv`` of ``Monitor(env)`` +
``VecNormalize``), the demo's training, all seeded alike:

- ``bare``: the Gymnasium env alone (``make_base_env``: what ``gymnasium.make`` builds), no callback;
- ``layers``: the layers as ``train`` builds them (``env_factory.make_env(..., training=True)``
  with the default objective vector's overlay keys, human-baseline normalised, and the log
  callback), every term metered and its overlay term computed, with the overlay's scales set to
  0: the reward is the env's own (``r + J(t) - J(t-1)`` with ``J = 0``), so PPO trains the very
  same policy through the same episodes as ``bare`` (checked at the end: equal episode counts
  and equal weights) and the difference is the layers' own cost;
- ``overlay``: the same with the overlay's real scales, what ``train`` runs. Its reward differs,
  so its policy and episodes drift from ``bare``'s, which its ratio includes.

The three runs advance in turns of one PPO iteration each (a rollout of ``n_steps x num_envs``
env steps and its update: ``learn(..., reset_num_timesteps=False)`` goes on where the last call
stopped), timed one by one, in rounds of bare, layers, overlay, overlay, layers, bare: load that
drifts on the shared machine hits the arms alike within a round of a few seconds. A round's
ratio is an arm's two iterations' time over bare's two; reported: the median round ratio (wall
and process CPU time; the cost is ``ratio - 1``; goal for ``layers``: <= 1.02) with its
quartiles, over the whole run (from the first step, as ``train`` runs it) and over its second
half (longer episodes). Last, the layers' own time *in situ* in a separate overlay run (the
clock read when the Gymnasium env inside returns and when the wrapper returns, plus the
callback's ``_on_step``) as a share of ``learn``'s wall time: a figure that moves less, to
compare code changes by. ``--hp`` overrides the catalog's PPO hyperparameters in every arm.

    .venv/bin/python benchmarks/economic_layers_cost.py [--rounds 30] [--insitu-steps 16384] [--hp '{}']
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import random
import statistics
import time

os.environ.setdefault("OMP_NUM_THREADS", "1")

import gymnasium as gym
import numpy as np
import torch
from stable_baselines3 import PPO
from stable_baselines3.common.monitor import Monitor
from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

from econmotor.config.objective_profile import ObjectiveVector
from econmotor.motor_backend.mujoco.backend import MujocoBackend
from econmotor.motor_backend.mujoco.env_factory import EnvRecipe, make_env
from econmotor.motor_backend.mujoco.randomization import make_base_env
from econmotor.motor_backend.mujoco.settings import merge_hyperparameters
from econmotor.motor_backend.mujoco.training import EconEpisodeLogCallback, policy_kwargs_from
from econmotor.motor_backend.sb3_callbacks import quiet_logger
from econmotor.objectives.loader import objective_from_vector
from econmotor.valuation import default_objective_vector

TASK = "hopper_courier"
ARMS = ("bare", "layers", "overlay")
#: the smallest run (tests/integration/test_benchmarks.py): one round of PPO iterations of 4 x 16 steps
SMOKE_ARGS: list[str] = ["--rounds", "1", "--insitu-steps", "64", "--hp", '{"n_steps": 16, "n_epochs": 1}']


def arm_recipe(recipe: EnvRecipe, arm: str) -> EnvRecipe:
    """``layers``: every overlay key kept, its scale 0 (the reward stays the env's own)."""
    return dataclasses.replace(recipe, scales=dict.fromkeys(recipe.scales, 0.0)) if arm == "layers" else recipe


def build_env(recipe: EnvRecipe, arm: str, seed: int) -> gym.Env:
    if arm == "bare":
        return make_base_env(recipe.settings.env_id, recipe.settings.env_kwargs, recipe.randomization)
    return make_env(arm_recipe(recipe, arm), seed=seed, training=True)


def time_inside(meter: gym.Env, own_s: list[float]) -> None:
    """Add the metering wrapper's own seconds per step (after the env inside returns) to ``own_s[0]``."""
    inner, meter_step, inner_step, returned = meter.env, meter.step, meter.env.step, [0.0]

    def timed_inner(action):
        out = inner_step(action)
        returned[0] = time.perf_counter()
        return out

    def timed_meter(action):
        out = meter_step(action)
        own_s[0] += time.perf_counter() - returned[0]
        return out

    inner.step, meter.step = timed_inner, timed_meter  # instance attributes: the callers use them


class TimedEconEpisodeLogCallback(EconEpisodeLogCallback):
    """The log callback, its ``_on_step`` seconds added to ``own_s[0]``."""

    def __init__(self, own_s: list[float]) -> None:
        super().__init__()
        self.own_s = own_s

    def _on_step(self) -> bool:
        start = time.perf_counter()
        out = super()._on_step()
        self.own_s[0] += time.perf_counter() - start
        return out


def rng_state() -> tuple:
    return random.getstate(), np.random.get_state(), torch.get_rng_state()


def set_rng_state(state: tuple) -> None:
    random.setstate(state[0])
    np.random.set_state(state[1])
    torch.set_rng_state(state[2])


class Run:
    """One arm's PPO run, advanced one iteration at a time. ``own_s``: time the layers in situ into it;
    ``hp``: overrides of the catalog's PPO hyperparameters."""

    def __init__(self, recipe: EnvRecipe, arm: str, seed: int, own_s: list[float] | None = None,
                 hp: dict | None = None) -> None:
        s = recipe.settings

        def build(i: int):
            def thunk():
                env = build_env(recipe, arm, seed + i)
                if own_s is not None:
                    time_inside(env, own_s)
                return Monitor(env)

            return thunk

        venv = DummyVecEnv([build(i) for i in range(s.num_envs)])
        venv.seed(seed)
        if s.normalize_obs:
            venv = VecNormalize(venv, norm_obs=True, norm_reward=False, clip_obs=10.0)
        self.venv = venv
        self.model = PPO("MlpPolicy", venv, seed=seed, device="cpu", verbose=0,
                         **policy_kwargs_from(merge_hyperparameters(s.algo_hyperparameters("ppo"), hp)))
        self.model.set_logger(quiet_logger())  # (SB3's default makes a temp folder at every learn)
        self.iteration_steps = self.model.n_steps * s.num_envs
        self.rng_state = rng_state()  # PPO draws from the global generators the model's seed set
        self.callback = None
        if arm != "bare":
            self.callback = TimedEconEpisodeLogCallback(own_s) if own_s is not None else EconEpisodeLogCallback()

    def advance(self, steps: int | None = None) -> tuple[float, float]:
        """(wall s, CPU s) of ``steps`` more env steps (default: one PPO iteration)."""
        set_rng_state(self.rng_state)  # the runs take turns: each draws its own random stream
        start, start_cpu = time.perf_counter(), time.process_time()
        self.model.learn(steps or self.iteration_steps, callback=self.callback, reset_num_timesteps=False)
        wall, cpu = time.perf_counter() - start, time.process_time() - start_cpu
        self.rng_state = rng_state()
        return wall, cpu

    def finish(self) -> tuple[int, float]:
        """Close the envs; (episodes run, a checksum of the policy's weights)."""
        episodes = sum(len(lengths) for lengths in self.venv.env_method("get_episode_lengths"))  # Monitor's
        weights = float(sum(p.detach().double().sum() for p in self.model.policy.parameters()))
        self.venv.close()
        return episodes, weights


def summary(rounds: list[tuple[float, float]]) -> str:
    """Median (quartiles) of the rounds' wall ratios, and the median CPU ratio."""
    wall = sorted(r[0] for r in rounds)
    q1, med, q3 = statistics.quantiles(wall, n=4) if len(wall) > 1 else (wall[0],) * 3
    return (f"wall {med:.3f} ({(med - 1) * 100:+.1f}%, quartiles {q1:.3f}-{q3:.3f}), "
            f"cpu {statistics.median(r[1] for r in rounds):.3f}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=30, help="rounds of two PPO iterations per arm")
    parser.add_argument("--insitu-steps", type=int, default=16384, help="env steps of the in-situ run")
    parser.add_argument("--hp", default="{}", help="JSON overrides of the catalog's PPO hyperparameters")
    args = parser.parse_args()
    torch.set_num_threads(1)
    objective = objective_from_vector(ObjectiveVector.from_list(default_objective_vector()), "default")
    recipe, _ = MujocoBackend().recipe(TASK, objective)
    s = recipe.settings
    hp = json.loads(args.hp)
    runs = {arm: Run(recipe, arm, seed=0, hp=hp) for arm in ARMS}
    steps = runs["bare"].iteration_steps
    print(f"{TASK}: PPO, {s.num_envs} envs, {steps} env steps per iteration, {args.rounds} rounds of 2 iterations "
          f"per arm ({2 * args.rounds * steps:,} steps per run), overlay keys {sorted(recipe.scales)}")
    ratios: dict[str, list[tuple[float, float]]] = {"layers": [], "overlay": []}
    for r in range(args.rounds):
        times = {arm: [0.0, 0.0] for arm in ARMS}
        for arm in (*ARMS, *reversed(ARMS)):
            wall, cpu = runs[arm].advance()
            times[arm][0] += wall
            times[arm][1] += cpu
        for arm in ratios:
            ratios[arm].append((times[arm][0] / times["bare"][0], times[arm][1] / times["bare"][1]))
        if r % 5 == 4 or r == args.rounds - 1:
            print(f"round {r + 1:3d}: bare {times['bare'][0]:5.2f} s | wall ratio "
                  + " ".join(f"{arm} {ratios[arm][-1][0]:.3f}" for arm in ratios), flush=True)
    finished = {arm: run.finish() for arm, run in runs.items()}
    if finished["layers"] != finished["bare"]:
        raise SystemExit(f"layers and bare trained different policies: {finished}")
    total = 2 * args.rounds * steps
    print("steps per episode: " + ", ".join(f"{arm} {total / finished[arm][0]:.0f}" for arm in ARMS)
          + " (bare and layers: the same episodes and weights, checked)")
    half = args.rounds // 2
    for arm, rs in ratios.items():
        note = "  (goal: <= 1.02)" if arm == "layers" else "  (includes the overlay's policy drift)"
        print(f"{arm:8s}/ bare, median round: whole run {summary(rs)}{note}")
        print(f"{'':10s}second half: {summary(rs[half:])}")
    own_s = [0.0]
    timed = Run(recipe, "overlay", seed=0, own_s=own_s, hp=hp)
    wall, _ = timed.advance(args.insitu_steps)
    timed.finish()
    print(f"layers in situ (a separate overlay run, {args.insitu_steps} steps): {own_s[0]:.3f} s of {wall:.2f} s "
          f"learn wall time = {own_s[0] / wall * 100:.2f}% ({own_s[0] / args.insitu_steps * 1e6:.1f} us per env step)")


if __name__ == "__main__":
    main()
