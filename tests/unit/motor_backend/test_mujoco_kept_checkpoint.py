"""Evaluation-driven training on real SB3 PPO keeps the checkpoint its held-out evaluations select, even
when that checkpoint is in the middle of the run: a scripted evaluation sequence (not deployable, deployable,
not deployable with the highest J) must leave the middle checkpoint's weights as the run's ``policy.zip``."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import torch
from stable_baselines3 import PPO

from econmotor.motor_backend.mujoco.backend import MujocoBackend
from econmotor.motor_backend.mujoco.run import TrainingRun
from econmotor.motor_backend.selection import SELECTION_SEED_OFFSET, selection_for
from econmotor.objectives import EconomicObjectiveSpec


def episode(legs: float, fell: bool) -> dict:
    """One 8 s courier episode's raw metrics (a fall ends it and counts as an attempted leg)."""
    return {"units_completed": legs, "units_attempted": legs + (1.0 if fell else 0.0), "errors": 1.0 if fell else 0.0,
            "episode_length_s": 8.0, "energy_wh": 0.05, "risk_score": 0.0, "novelty_score": 0.0,
            "return": 100.0 * legs, "length_steps": 1000.0, "termination_reason": "fall" if fell else "max_steps"}


EPISODES = 80  # 160 fall-free legs pass the sequential rule at its looks' confidence
# what the policy "does" at each held-out evaluation: falls often, then safe (acceptable), then fast but falling
# (the highest J of the three, not acceptable): the middle one is the one to keep
SCRIPT = ([episode(0.2, i % 2 == 0) for i in range(EPISODES)],
          [episode(2.0, False) for _ in range(EPISODES)],
          [episode(4.0, i % 3 == 0) for i in range(EPISODES)])


def weights(policy: torch.nn.Module) -> np.ndarray:
    return np.concatenate([p.detach().cpu().numpy().ravel() for p in policy.state_dict().values()])


class ScriptedRun(TrainingRun):
    """A real training run whose held-out evaluations return the scripted episodes, one set per evaluation,
    and remember the weights each evaluation saw."""

    seen: list[np.ndarray]
    seeds: list[int]

    def _held_out(self, model, num_episodes, first_seed, stop):
        self.seen.append(weights(model.policy))
        self.seeds.append(first_seed)
        return SCRIPT[len(self.seen) - 1][:num_episodes]


def test_a_mid_run_best_checkpoint_is_the_policy_kept(tmp_path: Path) -> None:
    backend = MujocoBackend()
    objective = EconomicObjectiveSpec()
    recipe, described = backend.recipe("hopper_courier", objective)
    every = 256
    run = ScriptedRun(run_dir=tmp_path / "run", recipe=recipe, described={**described, "task_id": "hopper_courier"},
                      algorithm="ppo", hyperparameters={"n_steps": 128, "batch_size": 64, "n_epochs": 1},
                      num_envs=1, max_steps=3 * every, seed=5, checkpoint_every_steps=10_000,
                      selection=selection_for(backend.catalog.get("hopper_courier"), objective, every, EPISODES,
                                              False, 5))
    run.seen, run.seeds = [], []
    run.train()
    assert len(run.seen) == 3 and run.seeds == [5 + SELECTION_SEED_OFFSET] * 3  # the same held-out episodes
    assert not np.array_equal(run.seen[1], run.seen[2])  # PPO updated between the evaluations
    record = run.config["selection"]
    assert [e["deployable"] for e in record["evaluations"]] == [False, True, False]
    assert record["evaluations"][2]["j_mean"] > record["evaluations"][1]["j_mean"]  # the last has the highest J
    assert record["kept"]["env_steps"] == 2 * every
    kept = PPO.load(str(run.run_dir / "policy.zip"), device="cpu")
    np.testing.assert_array_equal(weights(kept.policy), run.seen[1],  # the selected one, not the last
                                  err_msg="policy.zip is not the checkpoint the held-out evaluations selected")
