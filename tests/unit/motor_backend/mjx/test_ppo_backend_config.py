"""MjxBackend's edge: registration, num_envs on a CPU, hyperparameter and run-directory errors
(no training here: the end-to-end runs are in tests/integration/test_mjx_backend.py)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from econmotor.errors import ConfigError, UnknownNameError
from econmotor.motor_backend.factory import known_backends, make_motor_backend
from econmotor.motor_backend.mjx.backend import MjxBackend
from econmotor.motor_backend.mjx.device import device_description
from econmotor.objectives import EconomicObjectiveSpec


@pytest.fixture(scope="module")
def backend() -> MjxBackend:
    return make_motor_backend("mjx", compilation_cache_dir=None)


def test_registered_as_mjx_and_reports_its_device(backend: MjxBackend) -> None:
    assert "mjx" in known_backends() and backend.name == "mjx"
    assert device_description().startswith(("CPU", "GPU", "TPU"))


def test_num_envs_capped_on_a_cpu_and_said_so(backend: MjxBackend) -> None:
    settings = backend.settings("hopper_courier")
    assert settings.num_envs > settings.cpu_num_envs_cap  # the catalog asks for a GPU-sized batch
    used, note = backend.resolve_num_envs(settings, 0)
    assert used == settings.cpu_num_envs_cap and "capped" in note and str(settings.num_envs) in note
    assert backend.resolve_num_envs(settings, 8) == (8, "as requested")


def test_hyperparameters_merge_over_the_catalog_and_bad_ones_name_the_key(backend: MjxBackend) -> None:
    settings = backend.settings("hopper_courier")
    cfg = backend.ppo_config(settings, {"learning_rate": 1e-3})
    assert cfg.learning_rate == 1e-3 and list(cfg.hidden_sizes) == settings.ppo["hidden_sizes"]
    with pytest.raises(ConfigError, match="batch_size"):
        backend.ppo_config(settings, {"batch_size": 64})


def test_edge_errors_before_any_training(backend: MjxBackend, tmp_path: Path) -> None:
    objective = EconomicObjectiveSpec()
    with pytest.raises(ConfigError, match="PPO only"):
        backend.train_policy("hopper_courier", objective, [], 8, 100, 0, algorithm="sac")
    with pytest.raises(ConfigError, match="resume needs the run directory"):
        backend.train_policy("hopper_courier", objective, [], 8, 100, 0, resume=True)
    with pytest.raises(UnknownNameError):
        backend.train_policy("no_such_task", objective, [], 8, 100, 0)
    with pytest.raises(ConfigError, match="not an mjx run directory"):
        backend.evaluate_policy(str(tmp_path), "hopper_courier", objective, 1, 0)
    (tmp_path / "run_config.json").write_text(json.dumps({"task_id": "hopper_courier", "backend": "mujoco"}))
    with pytest.raises(ConfigError, match="not an mjx one"):
        backend.evaluate_policy(str(tmp_path), "hopper_courier", objective, 1, 0)
