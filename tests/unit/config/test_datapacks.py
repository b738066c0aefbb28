import pytest

from econmotor.config.datapacks import (
    DatapackProvider,
    load_datapack_configs,
    parse_datapack,
    save_datapack_config,
)
from econmotor.errors import ConfigError, UnknownNameError

SPEC_EXAMPLE = """\
id: logging_v1_base
description: "Baseline logging humanoid task"
motion_clips:
  - path: data/mocap/logging_clip_01.npz
    weight: 1.0
domain_randomization:
  terrain: "flat"
  friction_range: [0.5, 1.0]
curriculum:
  initial_difficulty: 0.1
  max_difficulty: 1.0
"""


def test_spec_example_loads(tmp_path):
    path = tmp_path / "dp.yaml"
    path.write_text(SPEC_EXAMPLE + "tags: [baseline]\ntask_tags: [locomotion]\nrobot_families: [humanoid]\n"
                    "objective_hint: safety\n")
    (pack,) = load_datapack_configs([path])
    assert pack.id == "logging_v1_base"
    assert pack.motion_clips[0].path == "data/mocap/logging_clip_01.npz"
    assert pack.domain_randomization == {"terrain": "flat", "friction_range": [0.5, 1.0]}
    assert pack.curriculum == {"initial_difficulty": 0.1, "max_difficulty": 1.0}
    assert (pack.tags, pack.task_tags, pack.robot_families, pack.objective_hint) == (
        ("baseline",), ("locomotion",), ("humanoid",), "safety")


def test_save_round_trip(tmp_path):
    pack = parse_datapack({"id": "a", "motion_clips": [{"path": "x.npz", "weight": 2}], "tags": ["t"],
                           "domain_randomization": {"friction_range": [0.1, 0.2]}, "objective_hint": "balanced"})
    path = save_datapack_config(pack, tmp_path / "sub" / "a.yaml")
    (loaded,) = load_datapack_configs([path])
    assert loaded.to_dict() == pack.to_dict()


def test_resolve_merges_in_order_later_keys_win():
    a = parse_datapack({"id": "a", "domain_randomization": {"friction_range": [0.5, 1.0], "terrain": "flat"},
                        "curriculum": {"initial_difficulty": 0.1}, "motion_clips": [{"path": "/c1.npz"}]})
    b = parse_datapack({"id": "b", "domain_randomization": {"terrain": "rough"},
                        "curriculum": {"max_difficulty": 0.8}, "motion_clips": [{"path": "/c2.npz", "weight": 3}]})
    provider = DatapackProvider([a])
    bundle = provider.resolve("hopper_courier", ["a", "b", "a"], [b])
    assert bundle.datapack_ids == ("a", "b")
    assert bundle.domain_randomization == {"friction_range": [0.5, 1.0], "terrain": "rough"}
    assert bundle.curriculum == {"initial_difficulty": 0.1, "max_difficulty": 0.8}
    assert [c.path for c in bundle.motion_clips] == ["/c1.npz", "/c2.npz"]
    assert bundle.clip_origins["/c2.npz"] == "b"
    # with no ids, every explicit config in order
    assert provider.resolve("t", [], [b, a]).datapack_ids == ("b", "a")


def test_unknown_id_lists_known():
    with pytest.raises(UnknownNameError, match="known datapack ids: a"):
        DatapackProvider([parse_datapack({"id": "a"})]).resolve("t", ["zz"])


@pytest.mark.parametrize("data, key", [
    ({"description": "no id"}, "id"),
    ({"id": "a", "motion_clip": []}, "motion_clip"),
    ({"id": "a", "motion_clips": {"path": "x"}}, "motion_clips"),
    ({"id": "a", "motion_clips": [{"path": "x", "weight": -1}]}, "motion_clips[0].weight"),
    ({"id": "a", "motion_clips": [{"weight": 1}]}, "motion_clips[0].path"),
    ({"id": "a", "curriculum": {"initial_difficulty": 2}}, "curriculum.initial_difficulty"),
    ({"id": "a", "curriculum": {"initial_difficulty": 0.9, "max_difficulty": 0.1}}, "curriculum.initial_difficulty"),
    ({"id": "a", "objective_hint": 3}, "objective_hint"),
    ({"id": "a", "tags": "x"}, None),
    ({"id": "a", "domain_randomization": [1]}, "domain_randomization"),
])
def test_bad_datapacks(data, key):
    if key is None:  # a single string tag is accepted as one tag
        assert parse_datapack(data, "dp.yaml").tags == ("x",)
        return
    with pytest.raises(ConfigError) as info:
        parse_datapack(data, "dp.yaml")
    assert info.value.key == key and "dp.yaml" in str(info.value)


def test_objective_hint_is_a_preset_or_free_text_kept_as_written(tmp_path):
    preset = parse_datapack({"id": "a", "objective_hint": "safety"})
    assert (preset.objective_hint, preset.objective_hint_preset) == ("safety", "safety")
    text = "prioritise throughput on fragile items"
    upstream = parse_datapack({"id": "b", "objective_hint": text})  # upstream schema: free text, not an error
    assert (upstream.objective_hint, upstream.objective_hint_preset) == (text, None)
    (loaded,) = load_datapack_configs([save_datapack_config(upstream, tmp_path / "b.yaml")])
    assert loaded.objective_hint == text
    assert parse_datapack({"id": "c", "objective_hint": "  "}).objective_hint is None
    bundle = DatapackProvider().resolve("t", [], [preset, upstream])
    assert (bundle.objective_hint, bundle.objective_hint_preset) == (text, None)


def test_a_free_text_hint_is_stored_in_the_registry_as_written(tmp_path):
    from econmotor.store import Registry

    text = "prioritise throughput on fragile items"
    with Registry(f"sqlite:///{tmp_path / 'reg.sqlite'}") as registry:
        registry.record_datapacks([parse_datapack({"id": "upstream", "objective_hint": text})])
        (stored,) = registry.datapack_configs(["upstream"])
    assert (stored.objective_hint, stored.objective_hint_preset) == (text, None)
