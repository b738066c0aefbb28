"""``econmotor shadow`` end to end: real SAC on dishwashing and a MuJoCo task, files on disk."""

from __future__ import annotations

import json
import os

import pytest

from econmotor.cli import main
from econmotor.networks.econ_objective_net import EconObjectiveNet

pytestmark = pytest.mark.slow


def test_shadow_run_writes_logs_plot_model_and_agrees_on_the_recorded_steps(tmp_path):
    out = tmp_path / "run"
    rc = main(["shadow", "--env", "dishwashing", "--objective-preset", "throughput", "--total-steps", "400",
               "--learning-starts", "100", "--eval-episodes", "1", "--seed", "1", "--save-dir", str(out),
               "--eval-preset", "safety"])
    assert rc == 0
    lines = [json.loads(x) for x in (out / "shadow_episodes.jsonl").read_text().splitlines()]
    assert lines and all(not r["flipped"] for r in lines)
    assert all(r["learner_sum"] == pytest.approx(r["legacy_sum"]) for r in lines)
    summary = json.loads((out / "shadow_summary.json").read_text())
    assert summary["steps"] == 400 and summary["episodes"] == len(lines)
    run = json.loads((out / "run.json").read_text())
    assert run["config"]["objective_label"] == "throughput"
    assert set(run["evaluation"]) == {"throughput", "safety"}
    assert (out / "sac_model.zip").is_file() and (out / "shadow_plot.png").is_file()


def test_flipped_lagrangian_net_run_logs_multipliers_and_saves_the_net(tmp_path, capsys):
    out = tmp_path / "flip"
    cfg = tmp_path / "cap.yaml"
    cfg.write_text("max_error_rate: 0.01\n")
    rc = main(["shadow", "--env", "dishwashing", "--objective-sampling", "dirichlet", "--use-objective-reward",
               "--constraints", str(cfg), "--constraint-mode", "lagrangian", "--reward-weights", "net",
               "--total-steps", "400", "--learning-starts", "100", "--eval-episodes", "1",
               "--max-episode-steps", "40", "--save-dir", str(out)])
    assert rc == 0
    lines = [json.loads(x) for x in (out / "shadow_episodes.jsonl").read_text().splitlines()]
    assert all(r["flipped"] for r in lines)
    assert len({tuple(r["objective_vector"]) for r in lines}) == len(lines)  # one vector per episode
    assert all("multipliers" in r["constraints"] for r in lines)
    assert max(r["constraints"]["multipliers"]["max_error_rate"] for r in lines) > 0
    run = json.loads((out / "run.json").read_text())
    assert run["multipliers"] and set(run["evaluation"]) == {"default", "throughput", "energy_saver", "safety"}
    assert all(set(m) == {"max_error_rate"} for m in run["multipliers"])  # multipliers only, no episode count
    printed = capsys.readouterr().out
    assert "objective default" not in printed and "sampled per episode from Dirichlet" in printed
    assert f"Lagrange multipliers at the end ({len(run['multipliers'])} dual updates, one per episode):" in printed
    # the registry names what it trained on: sampled objectives, not the first one it is evaluated on
    from econmotor.store.registry import Registry

    with Registry(os.environ["ECONMOTOR_DB_URL"], create=False) as registry:  # the suite's own (conftest)
        (recorded,) = registry.runs(kind="shadow")
    assert recorded.objective_name == "dirichlet"
    assert recorded.objective["first_evaluated_on"]["name"] == "default"
    # the net-mode run lists the net it saved among its files
    assert "econ_objective_net.pt" in printed
    net = EconObjectiveNet.load(out / "econ_objective_net.pt")
    assert net.reward_weights([1, 1, 1, 1, 0], *_features()).alpha_mpl > 0
    again = tmp_path / "again"
    assert main(["shadow", "--env", "dishwashing", "--reward-weights", "net", "--reward-net",
                 str(out / "econ_objective_net.pt"), "--total-steps", "50", "--learning-starts", "10",
                 "--eval-episodes", "0", "--max-episode-steps", "20", "--save-dir", str(again)]) == 0
    first = json.loads((again / "shadow_episodes.jsonl").read_text().splitlines()[0])
    # the step terms sum to the episode's: the net sees the episode's hours (20 one-minute steps)
    expected = net.reward_weights(first["objective_vector"], *_features(episode_steps=20)).to_list()
    assert first["reward_weights"] == pytest.approx(expected)


def _features(episode_steps=240):
    from econmotor.networks.econ_objective_net import EconFeatures, EnergyResponse
    from econmotor.tasks import get_task

    return EconFeatures.from_economics(get_task("dishwashing").economics), EnergyResponse(episode_steps / 60)


def test_shadow_runs_on_a_mujoco_task(tmp_path):
    out = tmp_path / "hopper"
    rc = main(["shadow", "--env", "hopper_courier", "--objective-preset", "balanced", "--total-steps", "300",
               "--learning-starts", "100", "--eval-episodes", "1", "--reward-weights", "analytic",
               "--save-dir", str(out)])
    assert rc == 0
    summary = json.loads((out / "shadow_summary.json").read_text())
    assert summary["steps"] == 300 and summary["episodes"] >= 1


def test_bad_inputs_are_one_line_errors(tmp_path, capsys):
    assert main(["shadow", "--env", "no_such_task", "--total-steps", "10", "--save-dir", str(tmp_path)]) == 2
    assert main(["shadow", "--reward-weights", "learned", "--total-steps", "10", "--save-dir", str(tmp_path)]) == 2
    assert "identity" in capsys.readouterr().err
