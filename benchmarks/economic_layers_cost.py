"""Wall time of a PPO training run with and without the economic layers, side by side in one run.

What a user feels: the cost of the economic layers inside a whole Stable-Baselines3 PPO run, not
per env step. The layers are the metering + overlay wrapper (``EconomicMeteringWrapper``, what
the mujoco backend trains on) and the callback that logs their episode figures
(``EconEpisodeLogCallback``). Every arm trains PPO on the hopper_courier catalog entry's env,
envs, hyperparameters and observation normalisation (``DummyVecEnv`` of ``Monitor(env)`` +
``VecNormalize`` + ``model.learn(steps)``), the demo's training:

- ``bare``: the Gymnasium env alone (``make_base_env``: what ``gymnasium.make`` builds), no callback;
- ``layers``: the layers as ``train`` runs them (``env_factory.make_env`` with the default
  objective vector's overlay keys, human-baseline normalised, and the log callback), every term
  metered and its overlay term computed, with the overlay's scales set to 0: the reward is the
  env's own (``r + J(t) - J(t-1)`` with ``J = 0``), so with the same seed PPO trains the very
  same policy through the same episodes as ``bare`` (checked: equal episode counts and equal
  final weights) and the difference is the layers' own cost;
- ``overlay``: the same with the overlay's real scales, what ``train`` runs. Its reward differs,
  so its policy and episodes drift from ``bare``'s (a falling hopper steps MuJoCo's contacts
  more), which its ratio includes.

Rounds run bare, layers, overlay, overlay, layers, bare (each arm's mean position is the same, so
load that drifts on a shared machine hits them alike), with the round's seed. Reported per round:
each arm's mean wall and process CPU seconds of ``learn`` and the ratios over ``bare``; then per
arm the median round ratio (wall and CPU; the cost is ``ratio - 1``; goal for ``layers``: <=
1.02). Last, the layers' own time *in situ* in one overlay run (the clock read when the Gymnasium
env inside returns and when the wrapper returns, plus the callback's ``_on_step``) as a share of
``learn``'s wall time: a figure that moves less from run to run, to compare code changes by.

``--pretrain N`` measures later in a run: a bare run trains N steps first and every arm goes on
from its weights and observation statistics (longer episodes, so the per-episode work weighs less).

    .venv/bin/python benchmarks/economic_layers_cost.py [--steps 16384] [--rounds 5] [--pretrain 0]
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import shutil
import statistics
import tempfile
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

import gymnasium as gym
import torch
from stable_baselines3 import PPO
from stable_baselines3.common.monitor import Monitor
from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

from econmotor.config.objective_profile import ObjectiveVector
from econmotor.motor_backend.mujoco.backend import MujocoBackend
from econmotor.motor_backend.mujoco.env_factory import EnvRecipe, make_env
from econmotor.motor_backend.mujoco.randomization import make_base_env
from econmotor.motor_backend.mujoco.training import EconEpisodeLogCallback, policy_kwargs_from
from econmotor.objectives.loader import objective_from_vector
from econmotor.valuation import default_objective_vector

TASK = "hopper_courier"
ARMS = ("bare", "layers", "overlay")


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


def train_seconds(recipe: EnvRecipe, arm: str, steps: int, seed: int, own_s: list[float] | None = None,
                  start: Path | None = None, save_to: Path | None = None) -> tuple[float, float, int, float]:
    """(wall s, CPU s) of ``PPO.learn(steps)`` on ``arm``'s envs, the episodes it ran and a checksum
    of the final weights; env and model construction are not timed. ``own_s``: time the layers
    in situ into it. ``start``: a folder with ``model.zip`` and ``vecnormalize.pkl`` to go on from;
    ``save_to``: a folder to write them to."""
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
    if start is not None:
        venv = VecNormalize.load(str(start / "vecnormalize.pkl"), venv) if s.normalize_obs else venv
        model = PPO.load(start / "model.zip", env=venv, device="cpu")
        model.set_random_seed(seed)
    else:
        if s.normalize_obs:
            venv = VecNormalize(venv, norm_obs=True, norm_reward=False, clip_obs=10.0)
        model = PPO("MlpPolicy", venv, seed=seed, device="cpu", verbose=0,
                    **policy_kwargs_from(s.algo_hyperparameters("ppo")))
    callback = None
    if arm != "bare":
        callback = TimedEconEpisodeLogCallback(own_s) if own_s is not None else EconEpisodeLogCallback()
    start, start_cpu = time.perf_counter(), time.process_time()
    model.learn(steps, callback=callback)
    wall, cpu = time.perf_counter() - start, time.process_time() - start_cpu
    episodes = sum(len(lengths) for lengths in venv.env_method("get_episode_lengths"))  # Monitor's
    weights = float(sum(p.detach().double().sum() for p in model.policy.parameters()))
    if save_to is not None:
        model.save(save_to / "model.zip")
        if isinstance(venv, VecNormalize):
            venv.save(str(save_to / "vecnormalize.pkl"))
    venv.close()
    return wall, cpu, episodes, weights


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=16384, help="env steps per training run")
    parser.add_argument("--rounds", type=int, default=5, help="A B C C B A rounds")
    parser.add_argument("--pretrain", type=int, default=0,
                        help="train a bare run this many steps first; every arm goes on from its weights "
                             "(later in a run: longer episodes)")
    args = parser.parse_args()
    torch.set_num_threads(1)
    objective = objective_from_vector(ObjectiveVector.from_list(default_objective_vector()), "default")
    recipe, _ = MujocoBackend().recipe(TASK, objective)
    s = recipe.settings
    print(f"{TASK}: PPO, {s.num_envs} envs, {args.steps} steps per run, overlay keys {sorted(recipe.scales)}")
    start = None
    if args.pretrain:
        start = Path(tempfile.mkdtemp(prefix="econmotor-layers-"))
        _, _, n, _ = train_seconds(recipe, "bare", args.pretrain, seed=1000, save_to=start)
        print(f"pretrained {args.pretrain} steps (bare, seed 1000, {args.pretrain / n:.0f} steps per episode); "
              "every run goes on from there")
    for arm in ARMS:  # warm up (imports, first allocations)
        train_seconds(recipe, arm, 2048, 99, start=start)
    ratios: dict[str, list[tuple[float, float]]] = {"layers": [], "overlay": []}
    episodes = dict.fromkeys(ARMS, 0)
    for r in range(args.rounds):
        runs: dict[str, list[tuple[float, float]]] = {arm: [] for arm in ARMS}
        same: dict[str, set[tuple[int, float]]] = {arm: set() for arm in ARMS}
        for arm in (*ARMS, *reversed(ARMS)):
            wall, cpu, n, weights = train_seconds(recipe, arm, args.steps, seed=r, start=start)
            runs[arm].append((wall, cpu))
            episodes[arm] += n
            same[arm].add((n, weights))
        if same["layers"] != same["bare"] or len(same["bare"]) != 1:
            raise SystemExit(f"round {r}: layers and bare trained different policies: {same}")
        mean = {arm: [sum(x) / len(x) for x in zip(*runs[arm], strict=True)] for arm in ARMS}
        for arm in ratios:
            ratios[arm].append((mean[arm][0] / mean["bare"][0], mean[arm][1] / mean["bare"][1]))
        print(f"round {r}: " + " | ".join(f"{arm} {mean[arm][0]:5.2f} s" for arm in ARMS)
              + " | wall/cpu ratio " + " ".join(f"{arm} {ratios[arm][-1][0]:.3f}/{ratios[arm][-1][1]:.3f}"
                                               for arm in ratios), flush=True)
    runs = 2 * args.rounds
    print(f"{args.rounds} rounds x 2 runs per arm; steps per episode: bare {runs * args.steps / episodes['bare']:.0f}, "
          f"layers {runs * args.steps / episodes['layers']:.0f} (same policies, checked), "
          f"overlay {runs * args.steps / episodes['overlay']:.0f}")
    for arm, rs in ratios.items():
        w, c = statistics.median(x[0] for x in rs), statistics.median(x[1] for x in rs)
        print(f"{arm:8s}/ bare training time, median round: wall {w:.3f} ({(w - 1) * 100:+.1f}%), "
              f"cpu {c:.3f} ({(c - 1) * 100:+.1f}%)" + ("  (goal: <= 1.02)" if arm == "layers" else
                                                        "  (includes the overlay's policy drift)"))
    own_s = [0.0]
    wall, _, _, _ = train_seconds(recipe, "overlay", args.steps, seed=0, own_s=own_s, start=start)
    print(f"layers in situ (overlay run, seed 0): {own_s[0]:.3f} s of {wall:.2f} s learn wall time = "
          f"{own_s[0] / wall * 100:.2f}% ({own_s[0] / args.steps * 1e6:.1f} us per env step)")
    if start is not None:
        shutil.rmtree(start)


if __name__ == "__main__":
    main()
