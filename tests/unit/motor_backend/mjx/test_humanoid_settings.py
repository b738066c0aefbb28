"""The humanoid couriers' settings without compiling a step: stress datapacks, reward terms, catalog entries."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from econmotor.config.datapacks import DatapackBundle, DatapackProvider, load_datapack_configs
from econmotor.errors import ConfigError
from econmotor.locomotion import rewards as lr
from econmotor.locomotion.stress import Stress
from econmotor.motor_backend.mjx.humanoid_env import (
    HUMANOID_LACKS,
    HumanoidWalkerEnv,
    check_humanoid_datapack,
)
from econmotor.robots import G1_29DOF
from econmotor.tasks import load_catalog
from econmotor.tasks.catalog import TaskCatalog

from .conftest import catalog_with_mjx_entry

REPO_DATAPACKS = "configs/datapacks"


def bundle(**dr) -> DatapackBundle:
    return DatapackBundle(task_id="humanoid_locomotion_g1", datapack_ids=("p",), domain_randomization=dr,
                          sources={"p": "packs/p.yaml"})


def humanoid_stress(*datapacks) -> Stress:
    """The stress the humanoid env reads from ``datapacks`` (its constructor's reading)."""
    return Stress.from_datapacks(datapacks, G1_29DOF.push_preset, 0.05, lacks=HUMANOID_LACKS)


def test_the_stress_datapack_is_drawn_as_the_evaluator_draws_it() -> None:
    [pack] = load_datapack_configs([f"{REPO_DATAPACKS}/humanoid_stress.yaml"])
    stress = humanoid_stress(bundle(**pack.domain_randomization))
    assert stress.friction_range == (0.4, 1.0) and stress.payload_kg_range == (2.0, 5.0)
    assert stress.push_interval_s == G1_29DOF.push_preset["push_interval_s"]  # "pushes: true": Holosoma's interval
    assert stress.max_push_vel_m_per_s == (0.5, 0.5) and stress.initial_joint_noise_rad == 0.05
    gains = humanoid_stress(bundle(kp_range=[0.9, 1.1], kd_range=[0.8, 1.2]))
    assert (gains.kp_range, gains.kd_range, gains.friction_range) == ((0.9, 1.1), (0.8, 1.2), None)
    with pytest.raises(ConfigError, match="packs/p.yaml: key 'domain_randomization.link_mass_range'"):
        humanoid_stress(bundle(link_mass_range=[0.9, 1.1]))
    with pytest.raises(ConfigError, match="packs/p.yaml: key 'domain_randomization.terrain'.*flat ground"):
        humanoid_stress(bundle(terrain="rough"))
    with pytest.raises(ConfigError, match="packs/p.yaml: key 'domain_randomization.ctrl_delay_steps'"):
        humanoid_stress(bundle(ctrl_delay_steps=[0, 2]))  # the C walker env applies it, this one cannot


@pytest.mark.parametrize(("name", "key"), [
    ("dishwashing_nominal.yaml", None), ("humanoid_stress.yaml", None),
    ("example_holosoma_datapack.yaml", "curriculum.initial_difficulty"), ("mujoco_hopper_mimic.yaml", "motion_clips"),
    ("dishwashing_varied_crockery.yaml", "domain_randomization.base_rate_range")])
def test_the_mjx_backend_checks_shipped_datapacks_as_before(name: str, key: str | None) -> None:
    """The two the humanoid env applied are accepted with their stress of before (printed from
    ``parse_humanoid_stress``, removed), the others refused naming the file and key."""
    [pack] = load_datapack_configs([f"{REPO_DATAPACKS}/{name}"])
    if key is None:
        check_humanoid_datapack(pack, pack.source)
        stress = humanoid_stress(DatapackProvider().resolve("humanoid_locomotion_g1", [pack.id], [pack]))
        assert stress == (Stress(initial_joint_noise_rad=0.05) if name.startswith("dish") else Stress(
            friction_range=(0.4, 1.0), payload_kg_range=(2.0, 5.0), push_interval_s=(5.0, 10.0),
            max_push_vel_m_per_s=(0.5, 0.5), initial_joint_noise_rad=0.05))
    else:
        with pytest.raises(ConfigError, match=rf"{name}: key '{key}'"):
            check_humanoid_datapack(pack, pack.source)


def test_expected_foot_height_rises_to_the_swing_height_and_back() -> None:
    phases = np.array([-math.pi, -math.pi / 2, 0.0, math.pi / 2, math.pi])
    heights = lr.expected_foot_height(phases, 0.09, np)
    np.testing.assert_allclose(heights, [0.0, 0.045, 0.09, 0.045, 0.0], atol=1e-12)


def test_an_unknown_reward_term_or_a_robot_written_in_the_mjx_entry_names_the_catalog_key() -> None:
    """The env's reward terms and time limit are the task's locomotion block's (its one place): a term no
    engine computes names the block's key; a robot written in the mjx entry is refused there."""
    task = "humanoid_locomotion_g1"
    spec = load_catalog().get(task)
    loco = dict(spec.locomotion)
    bad = replace(spec, locomotion={**loco, "rewards": {**loco["rewards"], "moonwalk": {"weight": 1.0}}},
                  source="my_tasks.yaml")
    with pytest.raises(ConfigError, match=r"my_tasks.yaml.*locomotion.rewards.moonwalk.*tracking_lin_vel"):
        HumanoidWalkerEnv(task, catalog=TaskCatalog({task: bad}))
    env = HumanoidWalkerEnv(task)
    assert env.episode_s == loco["sim2sim_episode_s"] and env.weights["feet_phase"] == 5.0
    assert env.reward_params["feet_phase"]["swing_height"] == loco["rewards"]["feet_phase"]["swing_height"]
    with pytest.raises(ConfigError, match=r"my_mjx.yaml.*humanoid_locomotion_g1.robot.*unknown key"):
        HumanoidWalkerEnv(task, catalog=catalog_with_mjx_entry(task, source="my_mjx.yaml", robot="g1_29dof"))
