"""End to end through the real Holosoma (classic MuJoCo, CPU) in .venv-holosoma.

G1 locomotion with the spec's example objective overlay and datapack: a few PPO
iterations, the run directory holding run_config.json and policy.onnx, the trained policy priced by the
same sim-to-sim evaluator as an imported one, and the deployed ONNX handle's metadata.
If .venv-holosoma is missing, the fixture builds it with ``make holosoma`` (minutes).
"""

from __future__ import annotations

import json
import math
import subprocess
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from econmotor.config.datapacks import load_datapack_configs
from econmotor.couriers.policy_import import find_holosoma_python
from econmotor.errors import BackendError
from econmotor.motor_backend.factory import make_motor_backend
from econmotor.motor_backend.holosoma.host.jobs import run_job
from econmotor.motor_backend.holosoma.job_specs import parse_job
from econmotor.motor_backend.onnx_policy import OnnxPolicyHandle
from econmotor.objectives import compile_economic_overlay, load_objective_spec

pytestmark = [pytest.mark.slow, pytest.mark.holosoma]
REPO = Path(__file__).resolve().parents[2]
OBJECTIVE = REPO / "configs" / "objectives" / "example_holosoma_objective.yaml"
DATAPACK = REPO / "configs" / "datapacks" / "example_holosoma_datapack.yaml"
ITERATIONS = 10
EPISODE_S = 4.0


@pytest.fixture(scope="module")
def holosoma_venv() -> Path:
    venv = REPO / ".venv-holosoma"
    if not (venv / ".econmotor-installed").exists():
        subprocess.run(["make", "holosoma"], cwd=REPO, check=True, timeout=1800)
    find_holosoma_python(venv)
    return venv


@pytest.fixture(scope="module")
def trained(holosoma_venv: Path, tmp_path_factory: pytest.TempPathFactory):
    backend = make_motor_backend("holosoma", simulator="mujoco", venv=holosoma_venv, eval_episode_length_s=EPISODE_S)
    objective = load_objective_spec(OBJECTIVE)
    packs = load_datapack_configs([DATAPACK])
    events: list[tuple[str, float, float]] = []
    result = backend.train_policy(
        "humanoid_locomotion_g1", objective, [], num_envs=2048, max_steps=24 * ITERATIONS, seed=3,
        datapack_configs=packs, output_dir=tmp_path_factory.mktemp("holosoma"), eval_episodes=2,
        progress=lambda label, done, total: events.append((label, done, total)),
    )
    return backend, objective, result, events


def test_request_is_adapted_to_one_cpu_env_and_announced(trained) -> None:
    _, _, result, events = trained
    messages = result.config["messages"]
    assert any("num_envs 2048 -> 1" in m for m in messages)
    assert any("stability_margin" in m and "ignored" in m for m in messages)
    assert any(label.startswith("holosoma: num_envs 2048 -> 1") for label, _, _ in events)
    train_progress = [(d, t) for label, d, t in events if label == "holosoma train"]
    assert train_progress[-1] == (ITERATIONS, ITERATIONS)
    assert any(label == "sim-to-sim episodes" for label, _, _ in events)
    assert result.config["plan"]["num_envs"] == 1 and result.config["plan"]["iterations"] == ITERATIONS


def test_overlay_terms_are_holosoma_reward_terms_and_logged(trained) -> None:
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    _, objective, result, _ = trained
    scales = compile_economic_overlay(objective)
    weights = result.config["overlay_weights"]
    assert set(weights) == {"mpl_per_hour", "energy_kwh", "error_rate", "risk_score"}
    for key, weight in weights.items():
        assert weight == pytest.approx(0.05 * scales[key])
        assert f"econ_{key}" in result.config["reward_terms"]
    tags = EventAccumulator(result.artifacts["tensorboard"]).Reload().Tags()["scalars"]
    assert "Episode/rew_econ_energy_kwh" in tags and "RawEpisode/raw_rew_econ_energy_kwh" in tags
    assert "Episode/rew_econ_mpl_per_hour" in tags and "Episode/rew_tracking_lin_vel" in tags
    assert result.config["econ_term_log"]["RawEpisode/raw_rew_econ_energy_kwh"] > 0  # joints did work
    assert result.config["overrides"]["randomization"]["randomize_friction_startup"]["friction_range"] == [0.5, 1.0]


def test_trained_run_is_priced_by_the_sim2sim_evaluator(trained) -> None:
    _, _, result, _ = trained
    run_dir = Path(result.policy_id)
    assert (run_dir / "run_config.json").is_file() and (run_dir / "policy.onnx").is_file()  # output_dir is the run
    provenance = result.config["evaluation"]["provenance"]  # the post-training evaluation's MotorEvalResult's
    assert provenance["evaluator"] == "sim2sim" and not provenance["imported"]
    assert result.raw_metrics["num_episodes"] == 2 and len(result.episodes) == 2
    for ep in result.episodes:
        assert 0 < ep["episode_length_s"] <= EPISODE_S + 1e-9
        assert ep["termination_reason"] in ("fall", "time_out", "max_steps")
        assert ep["energy_wh"] > 0 and 0 <= ep["risk_score"] <= 1
    assert result.raw_metrics["energy_wh"] == pytest.approx(sum(ep["energy_wh"] for ep in result.episodes))
    for key in ("mpl_units_per_hour", "error_rate", "energy_kwh", "energy_kwh_per_hour", "implied_wage_usd_per_hour",
                "wage_parity", "robot_cost_usd_per_hour", "risk_score", "novelty_score"):
        assert math.isfinite(result.econ_metrics[key]), key
    mean_power_w = result.raw_metrics["energy_wh"] * 3600 / result.raw_metrics["episode_length_s"]
    assert 1.0 < mean_power_w < 20_000.0  # a 35 kg humanoid's joints, through an 80 % drivetrain


def test_training_terms_and_the_evaluator_read_one_meter(trained) -> None:
    """One meter per robot: the train job's econ terms get the very constants the sim-to-sim job meters with."""
    _, _, result, _ = trained
    job = json.loads((Path(result.policy_id) / "train_job.json").read_text(encoding="utf-8"))
    meter = job["overlay"]["params"]["meter"]
    assert meter == result.config["evaluation"]["meter"]
    assert meter["idle_power_w"] > 0 and meter["fall_tilt_rad"] > meter["tilt_margin_rad"] > 0


def test_onnx_handle_carries_both_metadata(trained) -> None:
    backend, _, result, _ = trained
    handle = backend.deploy_policy_handle(result.policy_id)
    assert isinstance(handle, OnnxPolicyHandle)
    assert len(handle.dof_names) == 29 and len(handle.kp) == 29 and len(handle.kd) == 29
    assert handle.action_scale is not None
    assert handle.metadata["task_id"] == "humanoid_locomotion_g1"
    assert handle.metadata["objective"]["error_weight"] == 0.5
    assert handle.metadata["task_economics"]["wage_human_usd_per_hour"] == 18.0
    obs = np.zeros((3, handle.obs_dim), dtype=np.float32)
    assert handle.act(obs).shape == (3, handle.action_dim)


def test_holosoma_error_text_is_surfaced(trained, holosoma_venv: Path, tmp_path: Path) -> None:
    # The fixture's own train job, but 2 envs on classic MuJoCo: Holosoma itself refuses.
    _, _, result, _ = trained
    job = parse_job((Path(result.policy_id) / "train_job.json").read_text(encoding="utf-8"))
    job = replace(job, plan=replace(job.plan, num_envs=2, iterations=1), run_dir=str(tmp_path))
    with pytest.raises(BackendError) as info:
        run_job(holosoma_venv / "bin" / "python", job, tmp_path, lambda *a: None)
    text = str(info.value)
    assert "Holosoma train failed" in text and "Traceback" in text
    assert "ClassicBackend only supports single environment, got 2" in text
    assert str(tmp_path / "train.log") in text


def test_econmotor_core_runs_on_holosomas_numpy_1(holosoma_venv: Path) -> None:
    code = (
        "import numpy, econmotor.config, econmotor.objectives, econmotor.valuation, econmotor.motor_backend\n"
        "from econmotor.economics import EconomicMeter\n"
        "from econmotor.tasks import load_catalog\n"
        "from econmotor.motor_backend.results import summarize_episodes\n"
        "catalog = load_catalog()\n"
        "econ = catalog.get('humanoid_locomotion_g1').economics\n"
        "raw, metrics, eps = summarize_episodes([{'units_completed': 2.0, 'errors': 1.0, 'episode_length_s': 60.0,"
        " 'energy_wh': 5.0}], econ)\n"
        "print(numpy.__version__.split('.')[0], len(catalog.ids()) > 0, round(metrics['mpl_units_per_hour'], 6))\n"
    )
    out = subprocess.run([str(holosoma_venv / "bin" / "python"), "-c", code], capture_output=True, text=True,
                         check=True, cwd=REPO)
    assert out.stdout.split() == ["1", "True", "120.0"]
