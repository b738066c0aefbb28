"""``econmotor shadow``'s console output: rounded weights, multipliers only, what was trained, 80 columns.

Each test runs a real, small shadow SAC run on the dishwashing workcell (a few hundred steps), so the
lines checked are those a user gets; the exact figures of a run are read back from what it recorded.
"""

from __future__ import annotations

import json
import os
import re

import pytest

from econmotor.cli import main
from econmotor.cli.shadow import _fmt
from econmotor.rl import train_sac_objective as shadow_training
from econmotor.rl.lagrange import LagrangeMultipliers
from econmotor.store.registry import Registry
from econmotor.valuation import ConstraintSet

SMALL = ("--total-steps", "200", "--learning-starts", "100", "--max-episode-steps", "20", "--eval-episodes", "1")
LONG_FLOAT = re.compile(r"\d\.\d{5,}")  # a figure printed with more than a few digits


def _run(capsys, tmp_path, monkeypatch, *args: str) -> list[str]:
    monkeypatch.chdir(tmp_path)  # a short relative --save-dir: the run directory's path is the user's length
    assert main(["shadow", "--env", "dishwashing", "--save-dir", "run", *SMALL, *args]) == 0
    return capsys.readouterr().out.splitlines()


def _recorded_objective() -> dict:
    with Registry(os.environ["ECONMOTOR_DB_URL"], create=False) as registry:  # the suite's own (conftest)
        (run,) = registry.runs(kind="shadow")
    return run.objective


def test_weights_print_rounded_and_every_line_fits_80_columns(capsys, tmp_path, monkeypatch):
    lines = _run(capsys, tmp_path, monkeypatch, "--objective-preset", "throughput")
    text = "\n".join(lines)
    assert "0.4444444444444444" not in text and "0.2222222222222222" not in text
    assert "  mpl 0.444, error 0.222, energy 0.111, safety 0.222, novelty 0" in lines
    assert "trained on objective throughput, weights normalised to sum 1:" in lines
    pair = r"Pearson (nan|-?[\d.e+-]+), Spearman (nan|-?[\d.e+-]+)"
    assert re.fullmatch(rf"  per step: {pair}", lines[lines.index("  mpl 0.444, error 0.222, energy 0.111, "
                                                                  "safety 0.222, novelty 0") + 2])
    assert any(re.fullmatch(rf"  legacy episode sum vs episode J: {pair}", line) for line in lines)
    before_table = text.split("evaluation (deterministic)")[0]  # the weights and correlation lines
    assert not LONG_FLOAT.search(before_table), before_table
    assert max(len(line) for line in lines) <= 80, [line for line in lines if len(line) > 80]
    assert "Lagrange" not in text  # no constraints, no multipliers
    # the files actually written, not a fixed list
    saved = sorted(p.name for p in (tmp_path / "run").iterdir() if p.is_file())
    at = lines.index("shadow run #1 saved under run:")
    assert sorted(re.split(r"[,\s]+", " ".join(lines[at + 1:]).strip())) == saved
    # the recorded objective stays exact
    assert _recorded_objective()["vector"] == [2.0, 1.0, 0.5, 1.0, 0.0]


def test_a_dirichlet_header_says_what_is_trained_and_what_is_evaluated(capsys, tmp_path, monkeypatch):
    cap = tmp_path / "cap.yaml"
    cap.write_text("max_error_rate: 0.03\n")
    lines = _run(capsys, tmp_path, monkeypatch, "--objective-sampling", "dirichlet", "--use-objective-reward",
                 "--constraints", str(cap), "--constraint-mode", "lagrangian")
    text = "\n".join(lines)
    assert "objective default" not in text
    assert re.fullmatch(r"shadow run dishwashing: learner reward objective, \d+ steps/s", lines[0])
    assert lines[1:6] == [
        "trained on objectives sampled per episode from Dirichlet(1, 1, 1, 1, 0)",
        "  over the weights of mpl, error, energy, safety; novelty stays 0",
        "evaluated (table below) on: default, throughput, energy_saver, safety",
        "weights of default, normalised to sum 1:",
        "  mpl 0.741, error 0.148, energy 0.0741, safety 0.037, novelty 0",
    ]
    assert max(len(line) for line in lines) <= 80, [line for line in lines if len(line) > 80]
    assert _recorded_objective()["name"] == "dirichlet"


def test_the_multiplier_line_shows_multipliers_only_rounded_with_the_updates_in_words(capsys, tmp_path,
                                                                                      monkeypatch):
    cap = tmp_path / "cap.yaml"
    cap.write_text("max_error_rate: 0.03\n")
    lines = _run(capsys, tmp_path, monkeypatch, "--constraints", str(cap), "--constraint-mode", "lagrangian")
    multipliers = json.loads((tmp_path / "run" / "run.json").read_text())["multipliers"]
    assert len(multipliers) >= 2  # 200 steps of at most 20: one update per episode
    at = lines.index(f"Lagrange multipliers at the end ({len(multipliers)} dual updates, one per episode):")
    assert lines[at + 1] == f"  max_error_rate {_fmt(multipliers[-1]['max_error_rate'])}"  # 3 significant digits
    assert "episodes" not in lines[at + 1] and "{" not in lines[at + 1]  # no dict, no episode count in it


def test_the_multiplier_history_holds_multipliers_only():
    lag = LagrangeMultipliers(("max_error_rate", "min_wage_parity"), lr=0.5)
    lag.record({"max_error_rate": 0.2, "min_wage_parity": -1.0})
    lag.update()
    lag.record({"max_error_rate": 0.4, "min_wage_parity": 0.0})
    lag.record({"max_error_rate": 0.0, "min_wage_parity": 0.0})
    lag.update()
    assert [set(h) for h in lag.history] == [{"max_error_rate", "min_wage_parity"}] * 2
    assert lag.history[-1] == {"max_error_rate": pytest.approx(0.2), "min_wage_parity": 0.0}


def test_the_recorded_multipliers_of_a_lagrangian_run_are_multipliers_only(tmp_path):
    config = shadow_training.ShadowConfig(
        env="dishwashing", total_steps=80, learning_starts=100, eval_episodes=0, max_episode_steps=20,
        net_arch=(16, 16), batch_size=16, constraints=ConstraintSet(max_error_rate=0.001),
        constraint_mode="lagrangian", save_dir=str(tmp_path / "run"))
    result = shadow_training.train_sac_objective(config)
    assert len(result.multipliers) >= 3  # 80 steps of at most 20: one update per episode
    assert all(set(m) == {"max_error_rate"} for m in result.multipliers)
    run = json.loads((tmp_path / "run" / "run.json").read_text())
    assert run["multipliers"] == result.multipliers
