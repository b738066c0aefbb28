"""Wall time of a short PPO training run with and without the economic layers, same run.

What a user feels: the cost of the metering + overlay wrapper (``EconomicMeteringWrapper``, what
the mujoco backend trains on) inside a whole Stable-Baselines3 PPO run, not per env step. Every
arm trains PPO on the hopper_courier catalog entry's env, envs, hyperparameters and observation
normalisation (``DummyVecEnv`` of ``Monitor(env)`` + ``VecNormalize`` + ``model.learn(steps)``):

- ``bare``: the Gymnasium env alone (``make_base_env``: what ``gymnasium.make`` builds),
- ``meter``: the same env inside the metering wrapper without an overlay: the reward is the env's
  own, so with the same seed it trains the same policy through the same episodes as ``bare``
  (checked: equal episode counts) and the difference is the metering code alone,
- ``overlay``: the metering wrapper with the default objective vector's overlay, human-baseline
  normalised (``env_factory.make_env``, what ``train`` runs). Its reward differs, so its policy
  and episodes drift from ``bare``'s (a falling hopper steps MuJoCo's contacts more), which the
  ratio includes; so the wrapper's own time is also measured *in situ* (the clock read when the
  Gymnasium env inside returns and when the wrapper returns) as a share of ``learn``'s wall time,
  and the time spent inside the Gymnasium env is compared with a bare run's of the same seed.

Rounds run bare, meter, overlay, overlay, meter, bare (each arm's mean position is the same, so
load that drifts on a shared machine hits them alike) with the same seed per round. Reported:
per round each arm's mean wall and CPU seconds of ``learn``; then per arm the median round
ratio over ``bare`` (wall and process CPU time; the cost is ``ratio - 1``; goal: <= 1.02) and
its episodes, the overlay wrapper's in-situ share of the wall time, and the seconds spent inside
the Gymnasium env by an overlay run and a bare run of the same seed.

    .venv/bin/python benchmarks/economic_layers_cost.py [--steps 8192] [--rounds 3]
"""

from __future__ import annotations

import argparse
import os
import statistics
import time

os.environ.setdefault("OMP_NUM_THREADS", "1")

import gymnasium as gym
import torch
from stable_baselines3 import PPO
from stable_baselines3.common.monitor import Monitor
from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

from econmotor.config.objective_profile import ObjectiveVector
from econmotor.motor_backend.mujoco.backend import MujocoBackend
from econmotor.motor_backend.mujoco.env_factory import EnvRecipe, make_env
from econmotor.motor_backend.mujoco.metering import EconomicMeteringWrapper
from econmotor.motor_backend.mujoco.randomization import make_base_env
from econmotor.motor_backend.mujoco.training import policy_kwargs_from
from econmotor.objectives.loader import objective_from_vector
from econmotor.valuation import default_objective_vector

TASK = "hopper_courier"


ARMS = ("bare", "meter", "overlay")


def build_env(recipe: EnvRecipe, arm: str, seed: int) -> gym.Env:
    if arm == "bare":
        return make_base_env(recipe.settings.env_id, recipe.settings.env_kwargs, recipe.randomization)
    return make_env(recipe, seed=seed, overlay=arm == "overlay")


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


def time_env(env: gym.Env, env_s: list[float]) -> None:
    """Add the seconds spent inside the Gymnasium env (``gymnasium.make``'s chain) to ``env_s[0]``."""
    inner = env.env if isinstance(env, EconomicMeteringWrapper) else env
    inner_step = inner.step

    def timed(action):
        start = time.perf_counter()
        out = inner_step(action)
        env_s[0] += time.perf_counter() - start
        return out

    inner.step = timed  # an instance attribute: the wrapper above (or Monitor) calls it


def train_seconds(recipe: EnvRecipe, arm: str, steps: int, seed: int, own_s: list[float] | None = None,
                  env_s: list[float] | None = None) -> tuple[float, float, int]:
    """(wall s, CPU s) of ``PPO.learn(steps)`` on ``arm``'s envs and the episodes it ran; env and
    model construction are not timed. ``own_s``: time the metering wrapper in situ into it;
    ``env_s``: time the Gymnasium env inside into it."""
    s = recipe.settings

    def build(i: int):
        def thunk():
            env = build_env(recipe, arm, seed + i)
            if env_s is not None:
                time_env(env, env_s)
            if own_s is not None:
                time_inside(env, own_s)
            return Monitor(env)

        return thunk

    venv = DummyVecEnv([build(i) for i in range(s.num_envs)])
    venv.seed(seed)
    if s.normalize_obs:
        venv = VecNormalize(venv, norm_obs=True, norm_reward=False, clip_obs=10.0)
    model = PPO("MlpPolicy", venv, seed=seed, device="cpu", verbose=0,
                **policy_kwargs_from(s.algo_hyperparameters("ppo")))
    start, start_cpu = time.perf_counter(), time.process_time()
    model.learn(steps)
    wall, cpu = time.perf_counter() - start, time.process_time() - start_cpu
    episodes = sum(len(lengths) for lengths in venv.env_method("get_episode_lengths"))  # Monitor's
    venv.close()
    return wall, cpu, episodes


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=8192, help="env steps per training run")
    parser.add_argument("--rounds", type=int, default=3, help="A B B A rounds")
    args = parser.parse_args()
    torch.set_num_threads(1)
    objective = objective_from_vector(ObjectiveVector.from_list(default_objective_vector()), "default")
    recipe, _ = MujocoBackend().recipe(TASK, objective)
    s = recipe.settings
    print(f"{TASK}: PPO, {s.num_envs} envs, {args.steps} steps per run, overlay {sorted(recipe.scales)}")
    for arm in ARMS:  # warm up (imports, first allocations)
        train_seconds(recipe, arm, 2048, 99)
    ratios: dict[str, list[tuple[float, float]]] = {"meter": [], "overlay": []}
    episodes = dict.fromkeys(ARMS, 0)
    for r in range(args.rounds):
        runs: dict[str, list[tuple[float, float]]] = {arm: [] for arm in ARMS}
        for arm in (*ARMS, *reversed(ARMS)):
            wall, cpu, n = train_seconds(recipe, arm, args.steps, seed=r)
            runs[arm].append((wall, cpu))
            episodes[arm] += n
        mean = {arm: [sum(x) / len(x) for x in zip(*runs[arm], strict=True)] for arm in ARMS}
        for arm in ratios:
            ratios[arm].append((mean[arm][0] / mean["bare"][0], mean[arm][1] / mean["bare"][1]))
        print(f"round {r}: " + " | ".join(f"{arm} {mean[arm][0]:5.2f} s wall {mean[arm][1]:5.2f} s cpu" for arm in ARMS)
              + " | ratio wall/cpu " + " ".join(f"{arm} {ratios[arm][-1][0]:.3f}/{ratios[arm][-1][1]:.3f}"
                                                for arm in ratios), flush=True)
    own_s, env_s, bare_env_s = [0.0], [0.0], [0.0]
    wall, _, _ = train_seconds(recipe, "overlay", args.steps, seed=0, own_s=own_s, env_s=env_s)
    bare_wall, _, _ = train_seconds(recipe, "bare", args.steps, seed=0, env_s=bare_env_s)
    print(f"{TASK}: PPO, {s.num_envs} envs, {args.steps} steps x {args.rounds} rounds x 2 runs per arm; "
          f"episodes bare {episodes['bare']}, meter {episodes['meter']}, overlay {episodes['overlay']}")
    for arm, rs in ratios.items():
        w, c = statistics.median(x[0] for x in rs), statistics.median(x[1] for x in rs)
        print(f"{arm:8s}/ bare training time, median round: wall {w:.3f} ({(w - 1) * 100:+.1f}%), "
              f"cpu {c:.3f} ({(c - 1) * 100:+.1f}%)  (goal: <= 1.02)")
    print(f"overlay wrapper in situ: {own_s[0]:.3f} s of {wall:.2f} s learn wall time = {own_s[0] / wall * 100:.2f}% "
          f"({own_s[0] / args.steps * 1e6:.1f} us per env step)")
    print(f"inside the Gymnasium env (seed 0): bare {bare_env_s[0]:.2f} s of {bare_wall:.2f} s, "
          f"overlay {env_s[0]:.2f} s of {wall:.2f} s: the overlay-trained policy's physics differ by "
          f"{(env_s[0] - bare_env_s[0]) / bare_wall * 100:+.1f}% of bare's learn time")


if __name__ == "__main__":
    main()
