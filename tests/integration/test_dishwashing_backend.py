"""The dishwashing backend really trains SB3 SAC, saves, evaluates and deploys."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from econmotor.config.datapacks import parse_datapack
from econmotor.config.objective_profile import ObjectiveVector
from econmotor.envs import DishwashingEnv
from econmotor.errors import BackendError, ConfigError, UnknownNameError
from econmotor.motor_backend import make_motor_backend
from econmotor.objectives import objective_from_vector

THROUGHPUT = objective_from_vector(ObjectiveVector.from_preset("throughput"), "throughput")


@pytest.fixture(scope="module")
def trained(tmp_path_factory):
    out = tmp_path_factory.mktemp("runs")
    calls = []
    pack = parse_datapack({"id": "dw_rates", "domain_randomization": {"base_rate_range": [1.8, 2.2]},
                           "curriculum": {"initial_difficulty": 0.0, "max_difficulty": 1.0, "ramp_steps": 1000}})
    backend = make_motor_backend("dishwashing")
    result = backend.train_policy("dishwashing", THROUGHPUT, ["dw_rates"], 2, 2000, 7, datapack_configs=[pack],
                                  output_dir=out, eval_episodes=3,
                                  progress=lambda label, done, total: calls.append((label, done, total)))
    return backend, result, out, calls


@pytest.mark.slow
def test_train_writes_policy_config_and_curve(trained):
    _, result, out, calls = trained
    run_dir = Path(result.policy_id)
    assert run_dir == out and (run_dir / "policy.zip").is_file()  # output_dir is the run directory
    config = json.loads((run_dir / "run_config.json").read_text())
    assert config["seed"] == 7 and config["num_envs"] == 2 and config["max_steps"] == 2000
    assert config["objective"]["name"] == "throughput" and config["datapack_ids"] == ["dw_rates"]
    assert config["randomization"]["ranges"] == {"base_rate": [1.8, 2.2]}
    assert result.training_curve and result.training_curve[-1]["timesteps"] >= 2000
    rows = [json.loads(line) for line in (run_dir / "curve.jsonl").read_text().splitlines()]
    assert rows[-1]["env_steps"] == result.training_curve[-1]["timesteps"]  # every chunk's row; the curve thinned
    assert {p["timesteps"] for p in result.training_curve} <= {float(r["env_steps"]) for r in rows}
    train_calls = [c for c in calls if c[0].startswith("train")]
    assert train_calls[0][1] == 0 and train_calls[-1][1] == train_calls[-1][2] == 2000
    assert ("evaluate", 3, 3) in calls


@pytest.mark.slow
def test_train_returns_raw_and_econ_metrics_of_evaluation_episodes(trained):
    _, result, _, _ = trained
    assert len(result.episodes) == 3 and result.raw_metrics["num_episodes"] == 3
    raw, econ = result.raw_metrics, result.econ_metrics
    assert raw["units_completed"] == sum(ep["units_completed"] for ep in result.episodes)
    assert econ["mpl_units_per_hour"] == pytest.approx(raw["units_completed"] / (raw["episode_length_s"] / 3600))
    assert 0 <= econ["error_rate"] <= 0.5 and econ["energy_wh"] > 0
    for ep in result.episodes:
        assert ep["termination_reason"] in ("catastrophic_error", "sla_violation", "zero_throughput", "max_steps")
        assert {"mpl_episode", "error_rate_episode", "energy_Wh", "wage_parity"} <= set(ep)


@pytest.mark.slow
def test_evaluate_is_deterministic_and_the_handle_acts(trained):
    backend, result, _, _ = trained
    first = backend.evaluate_policy(result.policy_id, "dishwashing", THROUGHPUT, 2, 123)
    again = backend.evaluate_policy(result.policy_id, "dishwashing", THROUGHPUT, 2, 123)
    assert first.raw_metrics == again.raw_metrics and first.raw_metrics["num_episodes"] == 2
    handle = backend.deploy_policy_handle(result.policy_id)
    env = DishwashingEnv()
    obs, _ = env.reset(seed=0)
    action = handle.act(obs)
    assert action.shape == (2,) and np.all((action >= 0) & (action <= 1))
    batch = handle.act(np.stack([obs, obs]))
    assert batch.shape == (2, 2) and np.allclose(batch[0], action)


def test_bad_inputs_name_what_to_fix(tmp_path):
    backend = make_motor_backend("dishwashing")
    bad_pack = parse_datapack({"id": "bad", "domain_randomization": {"friction_range": [0.5, 1.0]}}, "bad.yaml")
    with pytest.raises(ConfigError, match="base_rate_range"):
        backend.train_policy("dishwashing", THROUGHPUT, [], 1, 10, 0, datapack_configs=[bad_pack],
                             output_dir=tmp_path)
    with pytest.raises(UnknownNameError, match="dishwashing"):
        backend.train_policy("dishwashin", THROUGHPUT, [], 1, 10, 0, output_dir=tmp_path)
    with pytest.raises(BackendError, match="policy.zip"):
        backend.deploy_policy_handle(str(tmp_path / "missing.zip"))


@pytest.mark.parametrize("name,weights", [
    ("example_objective", {"mpl_per_hour": 1.0, "energy_kwh": -0.2, "error_rate": -0.5, "risk_score": -0.3,
                           "stability_margin": -0.1}),
    ("throughput", {"mpl_per_hour": 2.0, "error_rate": -1.0, "energy_kwh": -0.5, "risk_score": -1.0}),
    ("energy_saver", {"mpl_per_hour": 1.0, "error_rate": -1.0, "energy_kwh": -3.0, "risk_score": -1.0}),
    ("safety", {"mpl_per_hour": 0.5, "error_rate": -2.0, "energy_kwh": -1.0, "risk_score": -3.0}),
])
def test_shipped_objectives_compile_to_the_documented_overlays(name, weights):
    from econmotor.objectives import compile_economic_overlay, load_objective_spec

    root = Path(__file__).resolve().parents[2] / "configs" / "objectives"
    spec = load_objective_spec(root / f"{name}.yaml")
    assert spec.name == name and compile_economic_overlay(spec).to_dict() == weights
    assert DishwashingEnv(objective=spec).ignored_overlay_keys == (("stability_margin",) if "stability_margin"
                                                                    in weights else ())


def test_human_baseline_training_objective_prices_energy_per_hour_worked():
    from econmotor.config.econ_params import EconParams
    from econmotor.config.task_economics import TaskEconomics
    from econmotor.motor_backend.dishwashing.backend import term_references, training_objective

    energy_saver = objective_from_vector(ObjectiveVector.from_preset("energy_saver"), "energy_saver")
    trained_on = training_objective(energy_saver, "human_baseline")
    assert trained_on.energy_weight == 0 and trained_on.extra_weights["energy_kwh_per_hour"] == -3.0
    assert trained_on.mpl_weight == 1.0 and trained_on.risk_weight == 1.0
    assert training_objective(energy_saver, "none") is energy_saver
    refs = term_references(EconParams.preset("toy"), TaskEconomics())
    # human pace: 60 good units/h at 5% errors = 63.16 attempts/h at 0.05 Wh each
    assert refs["mpl_per_hour"] == 60.0 and refs["error_rate"] == 0.05
    assert refs["energy_kwh_per_hour"] == pytest.approx(60 / 0.95 * 0.05 / 1000)
