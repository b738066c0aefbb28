"""Steps/s of SAC with shadow logging over the same SAC without it (goal: ratio >= 0.95).

Both arms train SB3 SAC on the dishwashing workcell with the legacy reward, same
seed and hyperparameters; the shadow arm adds the ShadowRewardWrapper (both rewards
per step, per-term sums, running Pearson/Spearman, JSONL per episode, plot at the
end) and its callback. Arms run in A B B A order per repeat, so a machine whose load
drifts during the run (2 shared cores) hits both arms alike. A second line times the
env alone (no learner) for the wrapper's raw cost per step, and a third gives the
ratio that cost implies at the measured SAC speed (load-independent); ``--env-steps`` (20,000)
random actions per env-alone arm.

    .venv/bin/python benchmarks/shadow_overhead.py [--steps 2000] [--repeats 1] [--env-steps 20000]
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np
import torch

from econmotor.rl.shadow_log import ShadowRecorder
from econmotor.rl.train_sac_objective import ShadowConfig, build_env, train_sac_objective

#: the smallest run (tests/integration/test_benchmarks.py): 4 SAC runs of 20 steps, 200 env-alone steps
SMOKE_ARGS: list[str] = ["--steps", "20", "--env-steps", "200"]


def sac_steps_per_s(shadow: bool, steps: int, seed: int) -> float:
    with tempfile.TemporaryDirectory() as tmp:
        config = ShadowConfig(env="dishwashing", objective_label="throughput", objective=(2, 1, 0.5, 1, 0),
                              total_steps=steps, learning_starts=min(500, steps // 4), seed=seed, shadow=shadow,
                              save_dir=tmp if shadow else None, eval_episodes=0)
        return train_sac_objective(config).steps_per_s


def env_steps_per_s(shadow: bool, steps: int) -> float:
    with tempfile.TemporaryDirectory() as tmp:
        config = ShadowConfig(env="dishwashing", shadow=shadow)
        env, _, _ = build_env(config, ShadowRecorder(tmp) if shadow else None)
        rng = np.random.default_rng(0)
        acts = rng.uniform(0, 1, size=(steps, 2)).astype(np.float32)
        env.reset(seed=0)
        start = time.perf_counter()
        for a in acts:
            *_, terminated, truncated, _ = env.step(a)
            if terminated or truncated:
                env.reset()
        return steps / (time.perf_counter() - start)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=2000)
    parser.add_argument("--repeats", type=int, default=1)
    parser.add_argument("--env-steps", type=int, default=20_000, help="random actions per env-alone arm")
    args = parser.parse_args()
    torch.set_num_threads(1)
    plain, shadow = [], []
    for r in range(args.repeats):
        for arm in (False, True, True, False):
            (shadow if arm else plain).append(sac_steps_per_s(arm, args.steps, seed=r))
            print(f"repeat {r}: SAC {'with' if arm else 'without'} shadow "
                  f"{(shadow if arm else plain)[-1]:.1f} steps/s", flush=True)
    env_plain = env_steps_per_s(False, args.env_steps)
    env_shadow = env_steps_per_s(True, args.env_steps)
    print(f"env only (no learner): without shadow {env_plain:.0f} steps/s, with shadow {env_shadow:.0f} steps/s, "
          f"ratio {env_shadow / env_plain:.3f}")
    cost_s = 1.0 / env_shadow - 1.0 / env_plain
    implied = 1.0 / (1.0 + cost_s * float(np.mean(plain)))
    print(f"shadow wrapper cost {cost_s * 1e6:.0f} us/step -> implied SAC ratio {implied:.4f} at "
          f"{np.mean(plain):.1f} steps/s")
    ratio = float(np.sum(shadow) / np.sum(plain))
    print(f"SAC steps/s with shadow / without: {np.mean(shadow):.1f} / {np.mean(plain):.1f} = ratio {ratio:.3f} "
          f"(goal >= 0.95) over {args.repeats} alternating repeats of {args.steps} steps")


if __name__ == "__main__":
    main()
