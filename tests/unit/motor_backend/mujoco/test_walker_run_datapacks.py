"""A walker training run trains under what it was asked to, or says which datapack key it cannot apply.

The batched walker env has no curriculum, no motion clips and flat ground only. A price notes such keys (the
policy was trained under them elsewhere, say in Holosoma), but a training run on the env would silently train
without them: it refuses them, naming the datapack file and the key, before anything is built.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from econmotor.config.datapacks import load_datapack_configs
from econmotor.errors import ConfigError
from econmotor.motor_backend.mujoco import walker_backend as wb
from econmotor.objectives.economic_objective import EconomicObjectiveSpec
from econmotor.tasks import get_task

DATAPACKS = Path(__file__).resolve().parents[4] / "configs" / "datapacks"


def _run(tmp_path: Path, pack: str) -> dict:
    packs = load_datapack_configs([DATAPACKS / pack])
    _, config = wb.walker_run(get_task("humanoid_locomotion_g1"), EconomicObjectiveSpec(), packs, tmp_path / "run",
                              num_envs=4, max_steps=1, seed=0, init_policy=None, hyperparameters=None,
                              selection=None, resume=False, max_wall_s=None, described={})
    return config


def test_a_walker_run_refuses_a_curriculum_naming_file_and_key(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match=r"example_holosoma_datapack\.yaml: key 'curriculum\.initial_difficulty'"):
        _run(tmp_path, "example_holosoma_datapack.yaml")
    assert not (tmp_path / "run").exists()


def test_a_walker_run_trains_under_the_stress_it_can_apply(tmp_path: Path) -> None:
    config = _run(tmp_path, "humanoid_stress.yaml")
    assert config["stress"]["friction_range"] == (0.4, 1.0) and config["notes"] == []
