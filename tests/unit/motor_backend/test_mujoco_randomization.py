"""Domain randomization and curriculum of the mujoco backend, read back from the MuJoCo model."""

import gymnasium as gym
import numpy as np
import pytest

from econmotor.config.datapacks import parse_datapack
from econmotor.errors import ConfigError
from econmotor.motor_backend.mujoco.backend import MujocoBackend
from econmotor.motor_backend.mujoco.randomization import (
    Curriculum,
    DomainRandomizationWrapper,
    make_base_env,
    parse_randomization,
)
from econmotor.objectives import EconomicObjectiveSpec


def test_friction_and_masses_are_redrawn_each_reset_within_the_ranges():
    dr, _ = parse_randomization({"friction_range": [0.5, 0.8], "mass_scale_range": [1.2, 1.5]}, {})
    base = gym.make("Hopper-v5")
    model = base.unwrapped.model
    friction0, mass0 = model.geom_friction[:, 0].copy(), model.body_mass.copy()
    env = DomainRandomizationWrapper(base, dr, seed=3)
    draws = []
    for seed in range(4):
        env.reset(seed=seed)
        ratio_f = model.geom_friction[:, 0] / friction0
        ratio_m = model.body_mass[1:] / mass0[1:]
        assert np.allclose(ratio_f, ratio_f[0]) and 0.5 <= ratio_f[0] <= 0.8
        assert np.all((ratio_m >= 1.2) & (ratio_m <= 1.5)) and model.body_mass[0] == mass0[0]
        draws.append(ratio_f[0])
    assert len(set(np.round(draws, 6))) == 4
    # a heavier body really changes the physics: the same actions give a different trajectory
    env.reset(seed=0)
    nominal = gym.make("Hopper-v5")
    nominal.reset(seed=0)
    for _ in range(30):
        env.step(np.full(3, 0.5))
        nominal.step(np.full(3, 0.5))
    assert not np.allclose(env.unwrapped.data.qpos, nominal.unwrapped.data.qpos)


def test_difficulty_scales_ranges_toward_nominal():
    dr, _ = parse_randomization({"friction_range": [0.2, 0.4], "action_noise_std": 0.3}, {})
    base = gym.make("Hopper-v5")
    friction0 = base.unwrapped.model.geom_friction[:, 0].copy()
    env = DomainRandomizationWrapper(base, dr, difficulty=0.0, seed=0)
    env.reset(seed=0)
    assert np.allclose(base.unwrapped.model.geom_friction[:, 0], friction0)
    env.set_difficulty(0.5)
    env.reset(seed=1)
    ratio = base.unwrapped.model.geom_friction[0, 0] / friction0[0]
    assert 0.6 <= ratio <= 0.7  # [1 + 0.5 (0.2 - 1), 1 + 0.5 (0.4 - 1)]


def test_curriculum_ramps_linearly_and_holds():
    cur = Curriculum(initial_difficulty=0.2, max_difficulty=0.8, ramp_steps=1000)
    assert [cur.difficulty(s) for s in (0, 500, 1000, 5000)] == pytest.approx([0.2, 0.5, 0.8, 0.8])
    assert Curriculum().difficulty(0) == 1.0


def test_curriculum_raises_difficulty_of_the_training_envs(tmp_path):
    pack = parse_datapack({"id": "ramp", "domain_randomization": {"friction_range": [0.5, 1.0],
                                                                  "terrain": "rough", "terrain_max_height_m": 0.04},
                           "curriculum": {"initial_difficulty": 0.0, "max_difficulty": 1.0, "ramp_steps": 512}})
    backend = MujocoBackend()
    result = backend.train_policy("hopper_courier", EconomicObjectiveSpec(), [], 2, 512, 0,
                                  datapack_configs=[pack], output_dir=tmp_path / "run", eval_episodes=0,
                                  hyperparameters={"n_steps": 64, "batch_size": 64, "n_epochs": 1})
    assert result.config["datapack_ids"] == ["ramp"]
    # the run's TensorBoard log records the ramp from 0 to 1
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    events = EventAccumulator(str(next((tmp_path / "run" / "tb").iterdir()))).Reload()
    values = [e.value for e in events.Scalars("curriculum/difficulty")]
    assert values[0] < 0.3 and values[-1] > 0.9 and values == sorted(values)
    # per-term episode sums go to TensorBoard raw and weighted, with the metered episode metrics
    tags = set(events.Tags()["scalars"])
    assert {"overlay/mpl_per_hour_raw", "overlay/mpl_per_hour_weighted", "econ/energy_wh"} <= tags


def test_rough_terrain_height_follows_difficulty():
    dr, _ = parse_randomization({"terrain": "rough", "terrain_max_height_m": 0.05}, {})
    base = make_base_env("Hopper-v5", {}, dr)
    model = base.unwrapped.model
    env = DomainRandomizationWrapper(base, dr, difficulty=1.0, seed=0)
    env.reset(seed=0)
    full = model.hfield_data.max() * model.hfield_size[0, 2]
    env.set_difficulty(0.25)
    env.reset(seed=0)
    quarter = model.hfield_data.max() * model.hfield_size[0, 2]
    assert full == pytest.approx(0.05, rel=0.05) and quarter == pytest.approx(0.25 * full, rel=1e-6)
    for _ in range(20):
        env.step(np.zeros(3))


@pytest.mark.parametrize(("dr", "cur", "key"), [
    ({"frction_range": [0.5, 1.0]}, {}, "domain_randomization.frction_range"),
    ({"friction_range": [1.0, 0.5]}, {}, "domain_randomization.friction_range"),
    ({"terrain": "lava"}, {}, "domain_randomization.terrain"),
    ({"push_force_n": 10.0}, {}, "domain_randomization.push_interval_s"),
    ({}, {"ramp": 10}, "curriculum.ramp"),
])
def test_bad_datapack_keys_name_the_datapack_and_key(dr, cur, key, tmp_path):
    pack = parse_datapack({"id": "bad_pack", "domain_randomization": dr or None, "curriculum": cur or None},
                          source=tmp_path / "bad_pack.yaml")
    with pytest.raises(ConfigError) as err:
        MujocoBackend().recipe("hopper_courier", EconomicObjectiveSpec(), [], [pack])
    assert err.value.key == key and "bad_pack" in str(err.value)


def test_shipped_mujoco_datapacks_are_valid_for_every_courier():
    from pathlib import Path

    from econmotor.config.datapacks import load_datapack_configs

    files = sorted((Path(__file__).parents[3] / "configs" / "datapacks").glob("mujoco_*.yaml"))
    assert files
    backend = MujocoBackend()
    for pack in load_datapack_configs(files):
        tasks = ("hopper_courier",) if pack.motion_clips else ("hopper_courier", "walker_courier")
        for task_id in tasks:
            recipe, described = backend.recipe(task_id, EconomicObjectiveSpec(), [], [pack])
            assert described["datapack_ids"] == [pack.id]
            assert recipe.randomization.active or (recipe.clips and "pose_tracking" in recipe.scales)
