"""``econmotor shadow``'s console output: rounded weights, multipliers only, what was trained, 80 columns.

The CLI tests swap the training for a stub that returns a fixed :class:`ShadowRunResult`
(with long unrounded floats and a real multiplier history), so they check the printing alone.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from econmotor.cli import main
from econmotor.rl import train_sac_objective as shadow_training
from econmotor.rl.lagrange import LagrangeMultipliers
from econmotor.valuation import ConstraintSet

EVAL_ROW = {"J": 70.37361196001999, "mpl_units_per_hour": 95.45795206971677, "error_rate": 0.0678796184488784,
            "energy_Wh_per_unit": 0.053730981489155935, "wage_parity": 1.2198197781218374}
SUMMARY = {"steps": 3000, "episodes": 38, "step_pearson": 0.7714149204888368, "step_spearman": 0.8435193787327633,
           "episode_pearson": 0.011286921415868718, "episode_spearman": 0.03884663790899596,
           "legacy_vs_J_pearson": 0.011286921415868807, "legacy_vs_J_spearman": 0.03884663790899596}


def _history(updates: int = 3) -> list[dict[str, float]]:
    lag = LagrangeMultipliers(("max_error_rate",), lr=1.0)
    for i in range(updates):
        lag.record({"max_error_rate": 3.6108327 + i})
        lag.update()
    return lag.history


@pytest.fixture
def stub_training(monkeypatch):
    """Replace SAC training: record the config, write run.json, return a canned result."""
    seen = {}

    def fake(config, progress):
        seen["config"] = config
        labels = shadow_training.eval_objectives(config)
        multipliers = _history() if config.constraint_mode == "lagrangian" else []
        Path(config.save_dir).mkdir(parents=True, exist_ok=True)
        (Path(config.save_dir) / "run.json").write_text("{}", encoding="utf-8")
        return shadow_training.ShadowRunResult(config.save_dir, dict(SUMMARY), dict.fromkeys(labels, EVAL_ROW),
                                               multipliers, 145.2, model=None)

    monkeypatch.setattr(shadow_training, "train_sac_objective", fake)
    return seen


def _run(capsys, tmp_path, monkeypatch, *args: str) -> list[str]:
    monkeypatch.chdir(tmp_path)  # a short relative --save-dir: the run directory's path is the user's length
    assert main(["shadow", "--env", "dishwashing", "--save-dir", "run", *args]) == 0
    return capsys.readouterr().out.splitlines()


def test_weights_print_rounded_and_every_line_fits_80_columns(stub_training, capsys, tmp_path, monkeypatch):
    lines = _run(capsys, tmp_path, monkeypatch, "--objective-preset", "throughput")
    text = "\n".join(lines)
    assert "0.4444444444444444" not in text and "0.2222222222222222" not in text
    assert "  mpl 0.444, error 0.222, energy 0.111, safety 0.222, novelty 0" in lines
    assert "trained on objective throughput, weights normalised to sum 1:" in lines
    assert "  per step: Pearson 0.771, Spearman 0.844" in lines
    assert "  legacy episode sum vs episode J: Pearson 0.0113, Spearman 0.0388" in lines
    assert max(len(line) for line in lines) <= 80, [line for line in lines if len(line) > 80]
    assert "Lagrange" not in text  # no constraints, no multipliers
    # the files actually written, not a fixed list
    assert lines[-2:] == ["shadow run #1 saved under run:", "  run.json"]
    # the recorded objective stays exact
    assert stub_training["config"].objective == (2.0, 1.0, 0.5, 1.0, 0.0)


def test_a_dirichlet_header_says_what_is_trained_and_what_is_evaluated(stub_training, capsys, tmp_path,
                                                                       monkeypatch):
    cap = tmp_path / "cap.yaml"
    cap.write_text("max_error_rate: 0.03\n")
    lines = _run(capsys, tmp_path, monkeypatch, "--objective-sampling", "dirichlet", "--use-objective-reward",
                 "--constraints", str(cap), "--constraint-mode", "lagrangian")
    text = "\n".join(lines)
    assert "objective default" not in text
    assert lines[0] == "shadow run dishwashing: learner reward objective, 145 steps/s"
    assert lines[1:6] == [
        "trained on objectives sampled per episode from Dirichlet(1, 1, 1, 1, 0)",
        "  over the weights of mpl, error, energy, safety; novelty stays 0",
        "evaluated (table below) on: default, throughput, energy_saver, safety",
        "weights of default, normalised to sum 1:",
        "  mpl 0.741, error 0.148, energy 0.0741, safety 0.037, novelty 0",
    ]
    assert max(len(line) for line in lines) <= 80, [line for line in lines if len(line) > 80]


def test_the_multiplier_line_shows_multipliers_only_rounded_with_the_updates_in_words(stub_training, capsys,
                                                                                      tmp_path, monkeypatch):
    cap = tmp_path / "cap.yaml"
    cap.write_text("max_error_rate: 0.03\n")
    lines = _run(capsys, tmp_path, monkeypatch, "--constraints", str(cap), "--constraint-mode", "lagrangian")
    at = lines.index("Lagrange multipliers at the end (3 dual updates, one per episode):")
    assert lines[at + 1] == "  max_error_rate 13.8"  # 3.61 + 4.61 + 5.61, 3 significant digits
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
    assert lag.history_episodes == [1, 2]  # the episode counts, beside the multipliers


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
