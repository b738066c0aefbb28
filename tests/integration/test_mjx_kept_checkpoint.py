"""Evaluation-driven training on the mjx backend keeps the checkpoint its held-out evaluations select, even
in the middle of the run, and records the held-out seeds it evaluated on (issue 35).

Real MJX PPO on the hopper courier (the task, num_envs and hyperparameters of test_mjx_backend.py, so the
training iteration comes from the same persistent compilation cache). Only the held-out evaluation is
scripted (as in tests/unit/motor_backend/test_mujoco_kept_checkpoint.py): it remembers the weights and the
first seed it was given and answers falling, then safe (acceptable), then fast but falling (the highest J,
not acceptable). The run's ``policy.npz`` must hold the weights of the middle evaluation.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from econmotor.motor_backend.selection import SELECTION_SEED_OFFSET

jax = pytest.importorskip("jax")

REPO = Path(__file__).resolve().parents[2]
EPISODES = 80


def episode(legs: float, fell: bool) -> dict:
    """One 8 s courier episode's raw metrics (a fall ends it and counts as an attempted leg)."""
    return {"units_completed": legs, "units_attempted": legs + (1.0 if fell else 0.0), "errors": 1.0 if fell else 0.0,
            "episode_length_s": 8.0, "energy_wh": 0.05, "risk_score": 0.0, "novelty_score": 0.0,
            "return": 100.0 * legs, "length_steps": 1000.0, "termination_reason": "fall" if fell else "max_steps"}


SCRIPT = ([episode(0.2, i % 2 == 0) for i in range(EPISODES)],
          [episode(2.0, False) for _ in range(EPISODES)],
          [episode(4.0, i % 3 == 0) for i in range(EPISODES)])


def flat(tree: object) -> np.ndarray:
    return np.concatenate([np.ravel(np.asarray(leaf, dtype=np.float64)) for leaf in jax.tree_util.tree_leaves(tree)])


@pytest.mark.slow
def test_mjx_keeps_the_mid_run_checkpoint_its_evaluations_selected(tmp_path: Path,
                                                                   monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("ECONMOTOR_JAX_CACHE_DIR", str(REPO / ".pytest_cache" / "econmotor-jax"))
    from econmotor.motor_backend.mjx import backend as mjx_backend
    from econmotor.objectives import EconomicObjectiveSpec

    seen: list[np.ndarray] = []
    seeds: list[int] = []

    def scripted(evaluator, batch, env, learner, n, first_seed, progress=None, label=None, stop=None):
        seen.append(flat(learner))
        seeds.append(int(first_seed))
        rows = SCRIPT[len(seen) - 1][:n]
        for done in range(batch, len(rows) + batch, batch):  # the backend asks stop after every batch
            if stop is not None and stop(rows[:done]):
                break
        return rows

    monkeypatch.setattr(mjx_backend, "evaluate_episodes", scripted)
    monkeypatch.setattr(mjx_backend.MjxBackend, "_evaluator", lambda self, env, cfg, ahead=False: None)
    backend = mjx_backend.MjxBackend(compilation_cache_dir=str(REPO / ".pytest_cache" / "econmotor-jax"))
    per_iteration = 8 * 20  # num_envs x the catalog's unroll_length
    result = backend.train_policy("hopper_courier", EconomicObjectiveSpec(), [], num_envs=8,
                                  max_steps=3 * per_iteration, seed=5, output_dir=tmp_path / "run",
                                  select_every_steps=per_iteration, select_episodes=EPISODES, eval_episodes=0)
    assert len(seen) == 3 and not np.array_equal(seen[0], seen[1]) and not np.array_equal(seen[1], seen[2])
    run_dir = Path(result.policy_id)
    with np.load(run_dir / "policy.npz") as data:
        n = len(json.loads(str(data["header"]))["shapes"])
        kept = np.concatenate([np.ravel(data[f"leaf_{i:04d}"].astype(np.float64)) for i in range(n)])
    assert np.array_equal(kept, seen[1])  # the acceptable middle one, not the last (the highest J)
    selection = json.loads((run_dir / "run_config.json").read_text(encoding="utf-8"))["selection"]
    assert selection["kept"]["env_steps"] == 2 * per_iteration and selection["kept_acceptable"] is True
    assert [e["env_steps"] for e in selection["evaluations"]] == [per_iteration, 2 * per_iteration,
                                                                   3 * per_iteration]
    # every held-out evaluation ran on the recorded seeds, apart from training's and the report's
    assert seeds == [5 + SELECTION_SEED_OFFSET] * 3
    assert selection["seeds"] == [5 + SELECTION_SEED_OFFSET, 5 + SELECTION_SEED_OFFSET + EPISODES]
