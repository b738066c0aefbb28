"""One episode, one J: a shadow-mode episode, exported and solved, scores the same J.

Shadow mode records the episode (``shadow_episodes.jsonl``, J from ``episode_j``);
``econmotor solve`` reads that file (and its own ``--export-jsonl`` of it) and scores the
run under the same objective vector: the utility of the one-episode run is the same J,
on the dishwashing workcell and on a MuJoCo courier task (both priced at 0.12 USD/kWh in
the catalog, so a Wh term on one path and a USD term on the other would differ).
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from econmotor.cli import main
from econmotor.config.objective_profile import ObjectiveVector
from econmotor.rl.shadow_log import EPISODES_FILE, ShadowRecorder
from econmotor.rl.train_sac_objective import ShadowConfig, build_env
from econmotor.valuation import episode_j


def record_one_shadow_episode(run_dir, env_id: str, energy_term: str, max_steps: int) -> dict:
    config = ShadowConfig(env=env_id, objective=tuple(ObjectiveVector.from_preset("energy_saver").to_list()),
                          objective_label="energy_saver", energy_term=energy_term, max_episode_steps=max_steps)
    recorder = ShadowRecorder(run_dir)
    env, task, _ = build_env(config, recorder)
    env.reset(seed=3)
    env.action_space.seed(3)
    done = False
    while not done:
        _, _, terminated, truncated, info = env.step(env.action_space.sample())
        done = terminated or truncated
    recorder.finish()
    env.close()
    record = info["shadow_episode"]
    assert record["task_id"] == env_id and task.economics.energy_price_usd_per_kwh == 0.12
    return record


def solved_j(tmp_path, episodes_file, vector: list[float], energy_term: str, name: str) -> tuple[float, str]:
    out = tmp_path / f"surface_{name}"
    args = ["solve", "--episodes-jsonl", str(episodes_file), "--vector", ",".join(repr(v) for v in vector),
            "--output-dir", str(out), "--export-jsonl", str(tmp_path / f"{name}_export.jsonl")]
    if energy_term != "wh":
        args += ["--energy-term", energy_term]
    assert main(args) == 0
    doc = json.loads((out / "objective_surface.json").read_text())
    (run,) = doc["runs"]
    (utility,) = run["utility"].values()
    return utility, run["run_id"]


@pytest.mark.parametrize("env_id, max_steps", [("dishwashing", 40), ("hopper_courier", 60)])
@pytest.mark.parametrize("energy_term", ["wh", "usd"])
def test_shadow_episode_exported_and_solved_scores_the_same_j(tmp_path, env_id, max_steps, energy_term):
    run_dir = tmp_path / f"shadow-{env_id}"
    record = record_one_shadow_episode(run_dir, env_id, energy_term, max_steps)
    vector = record["objective_vector"]  # the normalised energy_saver vector the episode was scored with
    j, run_id = solved_j(tmp_path, run_dir / EPISODES_FILE, vector, energy_term, "first")
    assert run_id == run_dir.name
    assert j == pytest.approx(record["episode_J"], rel=1e-9, abs=1e-9)
    # the solver's own export of the episode scores the same J again
    again, _ = solved_j(tmp_path, tmp_path / "first_export.jsonl", vector, energy_term, "second")
    assert again == pytest.approx(record["episode_J"], rel=1e-9, abs=1e-9)
    # and it is episode_j of the recorded summary (energy in Wh unless the objective prices it)
    econ = {**record["econ"], "energy_Wh_per_unit": record["econ"]["energy_Wh_per_unit"] or np.inf}
    expected = episode_j(econ, ObjectiveVector.from_list(vector, energy_term=energy_term),
                         type("Economics", (), {"energy_price_usd_per_kwh": 0.12})())
    assert record["episode_J"] == pytest.approx(expected, rel=1e-12)
    wh = record["econ"]["energy_Wh"]
    r_energy = -wh if energy_term == "wh" else -0.12 * wh / 1000.0
    assert record["episode_terms"]["r_energy"] == pytest.approx(r_energy, rel=1e-12)
