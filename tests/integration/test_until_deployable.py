"""Evaluation-driven training on real SB3 PPO and MuJoCo (issue 27): ``--until-deployable`` stops at
the first held-out evaluation that passes and records when; the kept policy is the best held-out
checkpoint; the report prices fresh episodes and says which checkpoint was kept and why.

An easy task makes a pass reachable in a few thousand steps: the hopper courier with an acceptance
rule any moving policy meets (fall-rate bound <= 1, any throughput), from a user tasks file.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import yaml

from econmotor.cli import main
from econmotor.motor_backend.mujoco.backend import MujocoBackend
from econmotor.motor_backend.mujoco.env_factory import make_env
from econmotor.motor_backend.mujoco.evaluation import load_policy, rollout_batched
from econmotor.motor_backend.selection import Selection, SelectionConfig
from econmotor.objectives import EconomicObjectiveSpec

pytestmark = pytest.mark.slow
CATALOG = Path(__file__).resolve().parents[2] / "src" / "econmotor" / "tasks" / "mujoco.yaml"


@pytest.fixture
def easy_tasks(tmp_path: Path) -> Path:
    task = yaml.safe_load(CATALOG.read_text())["tasks"]["hopper_courier"]
    task["acceptance"] = {"max_error_rate": {"value": 1.0, "source": "test: any fall rate"},
                          "min_units_per_hour": {"value": 0.0, "source": "test: any throughput"}, "error_name": "fall"}
    task["description"] = "hopper courier, accepted whenever it moves forward (test)"
    path = tmp_path / "easy.yaml"
    path.write_text(yaml.safe_dump({"tasks": {"hopper_easy": task}}))
    return path


def test_until_deployable_stops_early_records_when_and_the_report_prices_fresh_seeds(easy_tasks, tmp_path, capsys):
    out = tmp_path / "reports"
    rc = main(["report", "--task-id", "hopper_easy", "--tasks-file", str(easy_tasks), "--num-envs", "1",
               "--max-steps", "8192", "--until-deployable", "--select-every", "1024", "--select-episodes", "8",
               "--eval-episodes", "8", "--seed", "3", "--output-dir", str(out)])
    stdout = capsys.readouterr().out
    assert rc == 0, stdout[-3000:]
    (doc_path,) = out.glob("*.json")
    doc = json.loads(doc_path.read_text())
    backend_config = doc["runs"]["train"]["config"]["backend_config"]
    selection = backend_config["selection"]
    assert selection["became_deployable"]["env_steps"] == 1024 and selection["became_deployable"]["wall_s"] > 0
    assert backend_config["trained_steps"] < 8192  # stopped early: PPO finishes its 512-step rollout at most
    assert selection["evaluation_cost"]["count"] == 1 and selection["evaluation_cost"]["episodes"] == 8
    assert selection["kept"]["env_steps"] == 1024 and "training stopped once that was known" in selection["why"]
    # the report: its own evaluation run on fresh seeds, and which checkpoint was kept and why
    facts = doc["selection"]
    assert facts["fresh_seeds"] is True
    assert facts["priced_seeds"] == [3 + 1_000, 3 + 1_008] and facts["held_out_seeds"] == [50_003, 50_011]
    assert doc["runs"]["eval"]["seed"] == 1_003
    assert "policy kept: the checkpoint at 1,024 env steps" in stdout
    assert "policy kept" in doc_path.with_suffix(".md").read_text()


def test_the_kept_policy_is_the_best_held_out_checkpoint(easy_tasks, tmp_path):
    backend = MujocoBackend(task_files=[easy_tasks])
    objective = EconomicObjectiveSpec()
    result = backend.train_policy("hopper_easy", objective, [], 1, 4096, 0, output_dir=tmp_path / "run",
                                  eval_episodes=0, select_every_steps=1024, select_episodes=6)
    selection = result.config["selection"]
    evaluations = selection["evaluations"]
    assert [e["env_steps"] for e in evaluations] == [1024, 2048, 3072, 4096]
    best = max(evaluations, key=lambda e: (e["deployable"], e["j_mean"]))  # acceptable first, then J
    assert selection["kept"] == best and best["deployable"]
    # policy.zip is that checkpoint: its held-out episodes again give the recorded J
    recipe, _ = backend.recipe("hopper_easy", objective)
    recipe = backend.eval_recipe(recipe)
    _, act = load_policy(result.policy_id, "ppo")
    first = selection["seeds"][0]
    envs = [make_env(recipe, seed=first + i) for i in range(6)]
    rows = rollout_batched(envs, act, 6, first)
    for env in envs:
        env.close()
    j = Selection(backend.catalog.get("hopper_easy"), objective, SelectionConfig()).judge(rows)[2]
    assert j == pytest.approx(best["j_mean"], rel=1e-6)
    assert not (Path(result.policy_id) / "best").joinpath("policy.zip").samefile(Path(result.policy_id) / "policy.zip")
    # TensorBoard: the held-out fall-rate bound, units/h and J at every evaluation
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    (events,) = (Path(result.policy_id) / "tb").rglob("events.*")
    accumulator = EventAccumulator(str(events)).Reload()
    for tag in ("held_out/fall_rate_upper95", "held_out/units_per_hour", "held_out/J"):
        assert [e.step for e in accumulator.Scalars(tag)] == [1024, 2048, 3072, 4096], tag
