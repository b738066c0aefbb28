"""One reading of the datapacks into a walker's stress (``Stress.from_datapacks``), for both walker envs.

- every shipped datapack the walker setup accepted gives the stress it gave through Holosoma's terms
  (``map_datapacks`` then ``Stress.from_overrides``, removed; the values below were printed from that code),
  for the G1 and the T1; the ones it refused are still refused, naming the file and key;
- the push keys' defaults, ``pushes: false``, the rounded control delay and a negative payload read as before;
- what a walker env cannot apply is a ConfigError naming the file and key, or a note in ``Stress.ignored``
  (the pricing of a policy trained elsewhere): curriculum, motion clips, rough terrain, link masses, and a key
  the calling env says it lacks; with several packs, the one that set the key is named.
"""

from __future__ import annotations

import re
from dataclasses import replace
from pathlib import Path

import pytest

from econmotor.config.datapacks import DatapackConfig, DatapackProvider, MotionClipRef, load_datapack_configs
from econmotor.errors import ConfigError
from econmotor.locomotion.conditions import walker_setup
from econmotor.locomotion.stress import Stress
from econmotor.locomotion.task import walker_settings
from econmotor.robots import G1_29DOF
from econmotor.tasks import get_task

DATAPACKS = Path(__file__).resolve().parents[3] / "configs" / "datapacks"
PRESET = G1_29DOF.push_preset  # push_interval_s (5, 10) s, max_push_vel (1, 1) m/s: the T1's too
NOMINAL = Stress(initial_joint_noise_rad=0.05)  # the catalog's start-pose noise for both walker tasks
#: shipped datapack -> the stress the walker setup gave it before (the catalog's noise 0.05 rad), or the key
#: it was refused for
TODAY: dict[str, Stress | str] = {
    "dishwashing_nominal.yaml": NOMINAL,
    "dishwashing_varied_crockery.yaml": "domain_randomization.base_rate_range",
    "example_holosoma_datapack.yaml": replace(NOMINAL, friction_range=(0.5, 1.0)),
    "humanoid_stress.yaml": Stress(friction_range=(0.4, 1.0), payload_kg_range=(2.0, 5.0), push_interval_s=(5.0, 10.0),
                                   max_push_vel_m_per_s=(0.5, 0.5), initial_joint_noise_rad=0.05),
    "mujoco_hopper_mimic.yaml": NOMINAL,
    "mujoco_robust_locomotion.yaml": "domain_randomization.mass_scale_range",
    "mujoco_rough_terrain.yaml": "domain_randomization.terrain_max_height_m",
}


def setup_stress(task_id: str, path: Path) -> tuple[Stress, tuple[str, ...]]:
    spec = get_task(task_id)
    packs = load_datapack_configs([path])
    bundle = DatapackProvider().resolve(task_id, [p.id for p in packs], packs)
    setup = walker_setup(spec, walker_settings(spec), bundle, packs,
                         None)
    return setup.stress, setup.notes


def test_the_table_names_every_shipped_datapack() -> None:
    assert sorted(p.name for p in DATAPACKS.glob("*.yaml")) == sorted(TODAY)


@pytest.mark.parametrize("task_id", ["humanoid_locomotion_g1", "humanoid_locomotion_t1"])
@pytest.mark.parametrize("name", sorted(TODAY))
def test_every_shipped_datapack_gives_the_walker_setup_todays_stress(task_id: str, name: str) -> None:
    expected = TODAY[name]
    if isinstance(expected, str):
        with pytest.raises(ConfigError, match=rf"{name}: key '{expected}'"):
            setup_stress(task_id, DATAPACKS / name)
        return
    stress, notes = setup_stress(task_id, DATAPACKS / name)
    assert replace(stress, ignored=()) == expected
    assert all(name in entry for entry in stress.ignored)  # a note names its file
    assert ("nominal conditions" in " ".join(notes)) == (expected.push_interval_s is None
                                                       and expected.friction_range is None)


def test_what_the_walker_cannot_apply_is_a_note_naming_file_and_key_when_pricing() -> None:
    stress, notes = setup_stress("humanoid_locomotion_g1", DATAPACKS / "example_holosoma_datapack.yaml")
    source = str(DATAPACKS / "example_holosoma_datapack.yaml")
    assert stress.ignored == (
        f"{source}: curriculum.initial_difficulty (a walker env has no curriculum: its ranges apply as written)",
        f"{source}: curriculum.max_difficulty (a walker env has no curriculum: its ranges apply as written)",
        f"{source}: motion_clips (1 clip(s): a walker tracks the course's velocity commands, not clips "
        "(humanoid_wbt_g1 tracks clips))")
    assert notes[0].startswith("not applied in the sim-to-sim evaluation: " + source)


@pytest.mark.parametrize(("dr", "expected"), [  # printed from map_datapacks + Stress.from_overrides, noise 0.03
    ({"pushes": False, "max_push_vel_m_per_s": 0.3}, Stress(initial_joint_noise_rad=0.03)),
    ({"push_interval_s": [1.0, 2.0]}, Stress(push_interval_s=(1.0, 2.0), max_push_vel_m_per_s=(1.0, 1.0),
                                             initial_joint_noise_rad=0.03)),
    ({"max_push_vel_m_per_s": 0.7}, Stress(push_interval_s=(5.0, 10.0), max_push_vel_m_per_s=(0.7, 0.7),
                                           initial_joint_noise_rad=0.03)),
    ({"kp_range": [0.9, 1.1], "kd_range": [0.8, 1.2], "ctrl_delay_steps": [0.4, 2.6],
      "added_base_mass_kg": [-1.0, 2.0]},
     Stress(payload_kg_range=(-1.0, 2.0), initial_joint_noise_rad=0.03, kp_range=(0.9, 1.1), kd_range=(0.8, 1.2),
            ctrl_delay_steps=(0, 3))),
    ({"terrain": "plane", "initial_joint_noise_rad": 0.0}, Stress()),
])
def test_each_stress_key_reads_as_it_did_through_holosomas_terms(dr: dict, expected: Stress) -> None:
    pack = DatapackConfig(id="p", domain_randomization=dr, source="p.yaml")
    assert Stress.from_datapacks([pack], PRESET, 0.03) == expected
    bundle = DatapackProvider().resolve("t", ["p"], [pack])  # a resolved bundle reads the same
    assert Stress.from_datapacks([bundle], PRESET, 0.03) == expected


@pytest.mark.parametrize(("pack", "key"), [
    (DatapackConfig(id="p", domain_randomization={"link_mass_range": [0.9, 1.1]}, source="p.yaml"),
     "domain_randomization.link_mass_range"),
    (DatapackConfig(id="p", domain_randomization={"terrain": "rough"}, source="p.yaml"),
     "domain_randomization.terrain"),
    (DatapackConfig(id="p", curriculum={"initial_difficulty": 0.2}, source="p.yaml"), "curriculum.initial_difficulty"),
    (DatapackConfig(id="p", motion_clips=(MotionClipRef("c.npz"),), source="p.yaml"), "motion_clips"),
    (DatapackConfig(id="p", domain_randomization={"ctrl_delay_steps": [0, 1]}, source="p.yaml"),
     "domain_randomization.ctrl_delay_steps"),
])
def test_what_a_walker_env_cannot_apply_is_refused_naming_file_and_key(pack: DatapackConfig, key: str) -> None:
    with pytest.raises(ConfigError, match=rf"p.yaml: key '{key}': not applied by a walker env"):
        Stress.from_datapacks([pack], PRESET, lacks=("ctrl_delay_steps",))
    lenient = Stress.from_datapacks([pack], PRESET, lacks=("ctrl_delay_steps",), refuse_unapplied=False)
    assert len(lenient.ignored) == 1 and lenient.ignored[0].startswith(f"p.yaml: {key} (")


def test_unknown_keys_and_bad_values_name_the_pack_that_set_them() -> None:
    first = DatapackConfig(id="a", domain_randomization={"friction_range": [0.5, 1.0], "pushes": True}, source="a.yaml")
    second = DatapackConfig(id="b", domain_randomization={"friction_range": [0.2, 0.3]}, source="b.yaml")
    stress = Stress.from_datapacks([first, second], PRESET)
    assert stress.friction_range == (0.2, 0.3) and stress.push_interval_s == (5.0, 10.0)  # later packs win
    bad = DatapackConfig(id="b", domain_randomization={"friction_range": [1.0, 0.2]}, source="b.yaml")
    with pytest.raises(ConfigError, match=r"b.yaml: key 'domain_randomization.friction_range'"):
        Stress.from_datapacks([first, bad], PRESET)
    with pytest.raises(ConfigError, match=r"a.yaml: key 'domain_randomization.pushes'.*true or false"):
        Stress.from_datapacks([replace(first, domain_randomization={"pushes": "yes"})], PRESET)
    with pytest.raises(ConfigError, match=r"b.yaml: key 'domain_randomization.mass_scale_range'.*friction_range"):
        Stress.from_datapacks([first, replace(second, domain_randomization={"mass_scale_range": [0.9, 1.1]})],
                              PRESET, refuse_unapplied=False)


def test_the_walker_setup_names_the_pack_of_a_key_among_several() -> None:
    spec = get_task("humanoid_locomotion_g1")
    settings = walker_settings(spec)
    packs = [DatapackConfig(id="a", domain_randomization={"friction_range": [0.5, 1.0]}, source="a.yaml"),
             DatapackConfig(id="b", domain_randomization={"link_mass_range": [0.9, 1.1]}, source="b.yaml")]
    bundle = DatapackProvider().resolve(spec.task_id, ["a", "b"], packs)
    setup = walker_setup(spec, settings, bundle, packs, None)
    assert setup.stress.friction_range == (0.5, 1.0)
    assert setup.stress.ignored == ("b.yaml: domain_randomization.link_mass_range (a walker env scales no link "
                                    "masses)",)


def test_the_setup_carries_its_nominal_conditions(tmp_path: Path) -> None:
    """The conditions without the datapacks come with a setup (a training run's held-out looks alternate them
    with its stress): those a setup without datapacks has, the catalog's start noise even where a pack sets
    its own."""
    pack = tmp_path / "noisy.yaml"
    text = (DATAPACKS / "humanoid_stress.yaml").read_text()
    pack.write_text(re.sub(r"initial_joint_noise_rad: [0-9.]+", "initial_joint_noise_rad: 0.2", text))
    spec = get_task("humanoid_locomotion_g1")
    settings = walker_settings(spec)
    none = walker_setup(spec, settings, DatapackProvider().resolve(spec.task_id, [], []), [], None)
    for path in (DATAPACKS / "humanoid_stress.yaml", pack):
        packs = load_datapack_configs([path])
        setup = walker_setup(spec, settings, DatapackProvider().resolve(spec.task_id, [p.id for p in packs], packs),
                             packs, None)
        assert setup.nominal_stress == none.stress == none.nominal_stress == NOMINAL
        assert setup.stress != setup.nominal_stress
    assert setup.stress.initial_joint_noise_rad == 0.2
