"""benchmarks/g1_objectives.py: each objective is held to its own goal, any objective can be run, and a complete
run is kept as it is."""

from __future__ import annotations

import argparse
import importlib.util
import json
from pathlib import Path

import pytest

SCRIPT = Path(__file__).resolve().parents[3] / "benchmarks" / "g1_objectives.py"


@pytest.fixture(scope="module")
def bench():
    spec = importlib.util.spec_from_file_location("g1_objectives", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def condition(goals_by_run: dict[str, dict[str, bool]]) -> dict:
    return {"paired": {f"{run}-fastsac": {"goals": goals} for run, goals in goals_by_run.items()}}


def test_each_objective_is_shown_its_own_goal_and_an_unnamed_one_every_goal(bench) -> None:
    met = {"energy_cut": False, "faster": True, "falls_halved": False, "cheaper": True}
    runs = {f"{p}_s{s}": dict(met, energy_cut=s == 0) for p in ("energy_saver", "price_weighted") for s in (0, 1)}
    line = bench.goals_line(condition(runs), condition(runs), ["energy_saver", "price_weighted", "throughput"])
    saver, weighted = line.splitlines()  # throughput has no runs: no line
    assert saver.startswith("energy_saver: energy_cut on 1/2 seeds nominal, 1/2 under stress; cheaper")
    assert "faster" not in saver
    assert weighted.startswith("price_weighted: energy_cut on 1/2 seeds nominal, 1/2 under stress; faster on 2/2")
    assert "cheaper than its start on 2/2 nominal, 2/2 under stress; falls halved under stress on 0/2" in weighted


def test_every_objective_yaml_can_be_trained_for(bench, capsys) -> None:
    parser = bench.build_parser()
    assert parser.parse_args([]).presets == ["energy_saver", "throughput"]
    assert parser.parse_args(["--presets", "price_weighted", "safety"]).presets == ["price_weighted", "safety"]
    with pytest.raises(SystemExit):
        parser.parse_args(["--presets", "cheapest"])
    assert "invalid choice: 'cheapest'" in capsys.readouterr().err


def test_a_complete_run_is_kept_not_resumed(bench, tmp_path: Path, capsys, monkeypatch) -> None:
    run = tmp_path / "work" / "price_weighted_s0"
    run.mkdir(parents=True)
    (run / "policy.onnx").write_bytes(b"x")
    (run / "run_config.json").write_text(json.dumps({"backend": "mujoco", "trainer": "walker"}))
    (run / "curve.jsonl").write_text(json.dumps({"env_steps": 1003520, "wall_s": 510.0}) + "\n")

    def train_command(*_: object) -> list[str]:
        raise AssertionError("a complete run was trained again")

    monkeypatch.setattr(bench, "train_command", train_command)
    args = argparse.Namespace(presets=["price_weighted"], seeds=[0], minutes=30.0, max_steps=2_000_000,
                              num_envs=None, start="fastsac")
    bench.train(args, tmp_path / "results", tmp_path / "work")
    assert "kept price_weighted_s0: a complete run, 1,003,520 env steps" in capsys.readouterr().out
    assert (tmp_path / "results" / "price_weighted_s0.onnx").read_bytes() == b"x"


def test_a_recipe_setting_reaches_every_new_run_and_not_a_resumed_one(bench, tmp_path: Path) -> None:
    args = bench.build_parser().parse_args(["--hyperparameters", "j_pace=walker", "--hyperparameters", "gamma=0.995"])
    assert args.hyperparameters == ["j_pace=walker", "gamma=0.995"]
    new = bench.train_command("price_weighted", 0, tmp_path / "r", 30.0, 1000, None, "fastsac", False,
                              args.hyperparameters)
    assert new[new.index("--hyperparameters") + 1] == "j_pace=walker" and new[-2:] == ["--hyperparameters",
                                                                                         "gamma=0.995"]
    resumed = bench.train_command("price_weighted", 0, tmp_path / "r", 30.0, 1000, None, "fastsac", True,
                                  args.hyperparameters)
    assert "--hyperparameters" not in resumed  # a resumed run continues with the recipe it recorded
