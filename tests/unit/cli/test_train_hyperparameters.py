"""``train --hyperparameters KEY=VALUE``: one run's recipe over the catalog's, recorded in its run config; a
backend without a recipe, a resumed run, an item that is not KEY=VALUE and a key the learner lacks are one clear
line, exit 2, and record nothing."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from econmotor.cli import main
from econmotor.cli.options import hyperparameter_options
from econmotor.errors import ConfigError
from econmotor.motor_backend.factory import backend_class


@pytest.fixture
def workdir(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    monkeypatch.chdir(tmp_path)
    monkeypatch.delenv("ECONMOTOR_DB_URL", raising=False)
    return tmp_path


def test_each_value_is_read_as_yaml() -> None:
    got = hyperparameter_options(backend_class("mujoco"), ["gamma=0.998", "lr_bounds=[1.0e-6, 1.0e-4]",
                                                           "value_norm=false", " grad_clip = joint"])
    assert got == {"hyperparameters": {"gamma": 0.998, "lr_bounds": [1e-6, 1e-4], "value_norm": False,
                                       "grad_clip": "joint"}}
    assert hyperparameter_options(backend_class("dishwashing"), []) == {}


@pytest.mark.parametrize(("backend", "values", "resume", "said"), [
    ("dishwashing", ["gamma=0.9"], False, "backend 'dishwashing' has no recipe to set (allowed: mjx, mujoco)"),
    ("mujoco", ["gamma=0.9"], True, "continues with the recipe it recorded"),
    ("mujoco", ["gamma"], False, "expected KEY=VALUE"),
    ("mujoco", ["=0.9"], False, "expected KEY=VALUE"),
    ("mjx", ["lr_bounds=[1, 2"], False, "VALUE is not YAML"),
])
def test_a_recipe_that_cannot_be_set_is_refused(backend, values, resume, said) -> None:
    with pytest.raises(ConfigError, match="--hyperparameters") as err:
        hyperparameter_options(backend_class(backend), values, resume)
    assert said in str(err.value)


def test_the_walker_run_records_the_recipe_it_was_given(workdir: Path, capsys) -> None:
    base = ["train", "--motor-backend", "mujoco", "--task-id", "humanoid_locomotion_g1", "--max-steps", "64",
            "--num-envs", "2", "--select-episodes", "1", "--eval-episodes", "0"]
    assert main([*base, "--output-dir", "bad", "--hyperparameters", "gama=0.9"]) == 2
    err = " ".join(capsys.readouterr().err.split())
    assert "--hyperparameters: key 'gama': not a walker PPO setting" in err and "gamma" in err
    assert not (workdir / "bad").exists() and not (workdir / ".econmotor").exists()

    assert main([*base, "--output-dir", "run", "--hyperparameters", "gamma=0.995",
                 "--hyperparameters", "lr_bounds=[1.0e-6, 1.0e-4]"]) == 0
    recipe = json.loads((workdir / "run" / "run_config.json").read_text())["hyperparameters"]
    assert recipe["gamma"] == 0.995 and recipe["lr_bounds"] == [1e-6, 1e-4]
    assert recipe["num_envs"] == 2 and recipe["learning_rate"] == 3e-5  # the rest is the catalog's
