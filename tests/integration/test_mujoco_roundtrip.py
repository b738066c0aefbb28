"""mujoco backend end to end: train -> evaluate -> ONNX, record a clip, train on it with pose tracking."""

import json

import numpy as np
import pytest

from econmotor.cli import main
from econmotor.config.datapacks import load_datapack_configs, parse_datapack
from econmotor.errors import ConfigError
from econmotor.motor_backend.factory import make_motor_backend
from econmotor.motor_backend.mujoco.evaluation import load_policy
from econmotor.objectives import EconomicObjectiveSpec, compile_economic_overlay

FAST_PPO = {"n_steps": 128, "batch_size": 64, "n_epochs": 2}

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def trained(tmp_path_factory):
    backend = make_motor_backend("mujoco")
    objective = EconomicObjectiveSpec(mpl_weight=0.5, energy_weight=1.0, error_weight=2.0, name="roundtrip")
    result = backend.train_policy("hopper_courier", objective, [], 2, 1024, 0,
                                  output_dir=tmp_path_factory.mktemp("hopper") / "run", eval_episodes=2,
                                  hyperparameters=FAST_PPO)
    return backend, objective, result


def test_train_reports_metered_episodes_and_econ_metrics(trained):
    _, objective, result = trained
    assert result.backend == "mujoco" and result.raw_metrics["num_episodes"] == 2
    assert {"mpl_units_per_hour", "wage_parity", "robot_unit_cost_usd"} <= set(result.econ_metrics)
    for ep in result.episodes:
        assert ep["termination_reason"] in ("fall", "max_steps") and ep["energy_wh"] > 0
        assert ep["overlay_error_rate_raw"] == pytest.approx(ep["error_rate_episode"])
        assert ep["overlay_error_rate_weighted"] == pytest.approx(-2.0 * ep["error_rate_episode"] / 0.002)
    assert result.config["overlay"] == dict(compile_economic_overlay(objective))
    assert result.config["overlay_references"]["mpl_per_hour"] == 468.0  # human_baseline normalisation
    assert result.training_curve and result.training_curve[-1]["timesteps"] >= 1024


def test_evaluation_is_deterministic_and_uses_the_task_economics(trained):
    backend, objective, result = trained
    a = backend.evaluate_policy(result.policy_id, "hopper_courier", objective, 2, 7)
    b = backend.evaluate_policy(result.policy_id, "hopper_courier", objective, 2, 7)
    assert [e["return"] for e in a.episodes] == [e["return"] for e in b.episodes]
    assert a.econ_metrics["human_unit_cost_usd"] == pytest.approx(18.0 / 468.0)
    with pytest.raises(ConfigError, match="walker_courier"):
        backend.evaluate_policy(result.policy_id, "walker_courier", objective, 1, 0)


def test_onnx_handle_matches_the_torch_policy(trained):
    backend, _, result = trained
    handle = backend.deploy_policy_handle(result.policy_id)
    _, act = load_policy(result.policy_id, "ppo")
    obs = np.random.default_rng(0).normal(0.0, 2.0, size=(32, 11))
    torch_actions = np.stack([act(o) for o in obs])
    assert np.abs(handle.act(obs) - torch_actions).max() < 1e-5  # a dynamic batch of 32
    assert np.abs(handle.act(obs[0]) - torch_actions[0]).max() < 1e-5  # and a single observation
    meta = handle.metadata
    assert meta["task_id"] == "hopper_courier" and meta["overlay"]["error_rate"] == -2.0
    assert meta["obs_layout"]["obs_dim"] == 11 and len(meta["action_layout"]["actuators"]) == 3
    assert meta["economics"]["mp_human_units_per_hour"] == 468.0 and meta["datapack_ids"] == []


def test_recorded_clip_drives_pose_tracking_and_reference_init(trained, tmp_path):
    _, _, result = trained
    clip, pack_file = tmp_path / "hop.npz", tmp_path / "hop_pack.yaml"
    assert main(["datapacks", "record-clip", "--policy", result.policy_id, "--out", str(clip), "--steps", "60",
                 "--datapack-out", str(pack_file)]) == 0
    with np.load(clip) as data:
        assert data["qpos"].shape[1] == 6 and data["qpos"].shape[0] >= 2 and float(data["fps"]) == 125.0
    pack = load_datapack_configs([pack_file])[0]
    backend = make_motor_backend("mujoco")
    recipe, _ = backend.recipe("hopper_courier", EconomicObjectiveSpec(), [], [pack])
    from econmotor.motor_backend.mujoco.env_factory import make_env

    env = make_env(recipe, seed=0)
    env.reset(seed=0)
    frames = np.load(clip)["qpos"]
    qpos = env.unwrapped.data.qpos
    assert np.min(np.abs(frames[:, 1:] - qpos[1:]).max(axis=1)) < 1e-9  # started in a clip frame (RSI)
    run = backend.train_policy("hopper_courier", EconomicObjectiveSpec(), [], 1, 256, 1, datapack_configs=[pack],
                               output_dir=tmp_path / "mimic", eval_episodes=1, hyperparameters=FAST_PPO)
    ep = run.episodes[0]
    assert 0 < ep["pose_tracking"] <= ep["length_steps"]
    assert ep["overlay_pose_tracking_raw"] == pytest.approx(ep["pose_tracking"])
    assert run.config["overlay"]["pose_tracking"] == 1.0


def test_missing_clip_file_names_the_datapack(tmp_path):
    pack = parse_datapack({"id": "ghost", "motion_clips": [{"path": str(tmp_path / "none.npz")}]},
                          source=tmp_path / "ghost.yaml")
    with pytest.raises(ConfigError, match="ghost") as err:
        make_motor_backend("mujoco").recipe("hopper_courier", EconomicObjectiveSpec(), [], [pack])
    assert err.value.key == "motion_clips[0].path"


def test_cli_train_and_evaluate(tmp_path):
    out = tmp_path / "cli_run"
    assert main(["train", "--task", "hopper_courier", "--max-steps", "512", "--num-envs", "1",
                 "--eval-episodes", "1", "--output-dir", str(out), "--json", str(tmp_path / "t.json")]) == 0
    assert json.loads((tmp_path / "t.json").read_text())["policy_id"] == str(out)
    assert main(["evaluate", "--policy", str(out), "--task", "hopper_courier", "--episodes", "2",
                 "--output-dir", str(tmp_path / "ev")]) == 0
    assert len(json.loads((tmp_path / "ev" / "evaluation.json").read_text())["episodes"]) == 2
    assert main(["train", "--task", "hoper_courier", "--max-steps", "10"]) == 2


def test_sac_policy_exports_its_squashed_actor(tmp_path):
    backend = make_motor_backend("mujoco")
    result = backend.train_policy("hopper_courier", EconomicObjectiveSpec(), [], 1, 300, 2, output_dir=tmp_path / "sac",
                                  eval_episodes=1, algorithm="sac",
                                  hyperparameters={"learning_starts": 100, "batch_size": 32})
    assert result.config["algorithm"] == "sac" and result.config["hyperparameters"]["buffer_size"] == 1000
    _, act = load_policy(result.policy_id, "sac")
    obs = np.random.default_rng(1).normal(0.0, 1.0, size=(16, 11))
    actions = backend.deploy_policy_handle(result.policy_id).act(obs)
    assert np.abs(actions - np.stack([act(o) for o in obs])).max() < 1e-5
    assert np.all(np.abs(actions) <= 1.0)
