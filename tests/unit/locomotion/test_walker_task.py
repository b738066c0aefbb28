"""A walker task's one place: its catalog ``locomotion`` block (``locomotion/task.py``).

The robot card, the meter, the course and the reward terms of the G1's and T1's tasks are written once;
the holosoma, mujoco and mjx backends read them from there and their own entries hold only what is theirs.
"""

from __future__ import annotations

from dataclasses import replace

import pytest

from econmotor.errors import ConfigError
from econmotor.locomotion.task import (
    HOLOSOMA_KEYS,
    LOCOMOTION_KEYS,
    reward_terms,
    task_settings,
    walker_settings,
)
from econmotor.motor_backend.mjx.settings import OWN_KEYS, parse_mjx_settings
from econmotor.motor_backend.mujoco.walker_backend import WALKER_KEYS, walker_train_settings
from econmotor.tasks import load_catalog

WALKER_TASKS = ("humanoid_locomotion_g1", "humanoid_locomotion_t1")


@pytest.mark.parametrize("task_id", WALKER_TASKS)
def test_every_backend_reads_the_walker_task_from_its_locomotion_block(task_id: str) -> None:
    spec = load_catalog().get(task_id)
    block = walker_settings(spec)
    assert set(block) == set(LOCOMOTION_KEYS)
    # the backends' own entries hold nothing of the walker task
    assert set(spec.backends["holosoma"]) <= set(HOLOSOMA_KEYS)
    assert set(spec.backends["mjx"]) <= set(OWN_KEYS)
    assert set(spec.backends["mujoco"]["walker"]) <= set(WALKER_KEYS)
    holosoma = task_settings(spec)
    assert {k: holosoma[k] for k in block if k != "rewards"} == {k: v for k, v in block.items() if k != "rewards"}
    mjx = parse_mjx_settings(spec)
    assert mjx.robot == block["robot"] and mjx.course["dwell_s"] == block["dwell_s"]
    # one reward set: the CPU trainer's terms are the mjx couriers', Holosoma's ten
    weights, params = reward_terms(spec)
    trainer = walker_train_settings(spec)
    assert trainer.weights == weights == mjx.locomotion["weights"] and len(weights) == 10
    assert trainer.params == params == mjx.locomotion["params"]


def _g1(**changes):
    spec = load_catalog().get("humanoid_locomotion_g1")
    return replace(spec, source="my_tasks.yaml", **changes)


def test_a_walker_key_written_in_holosomas_entry_is_refused_there() -> None:
    spec = _g1()
    bad = replace(spec, backends={**spec.backends, "holosoma": {**spec.backends["holosoma"], "dwell_s": 5.0}})
    with pytest.raises(ConfigError) as info:
        task_settings(bad)
    assert info.value.source == "my_tasks.yaml"
    assert info.value.key == "tasks.humanoid_locomotion_g1.backends.holosoma.dwell_s"
    assert "written once in tasks.humanoid_locomotion_g1.locomotion" in info.value.detail


@pytest.mark.parametrize(("change", "key", "detail"), [
    ({"dwel_s": 20.0}, "locomotion.dwel_s", "unknown key"),
    ({"idle_power_w": -1.0}, "locomotion.idle_power_w", "must be >= 0"),
    ({"robot": "g9"}, None, "unknown robot 'g9'"),
    ({"rewards": {"moonwalk": {"weight": 1.0}}}, "locomotion.rewards.moonwalk", "reward term"),
], ids=["unknown-key", "negative-idle", "unknown-robot", "unknown-term"])
def test_a_bad_locomotion_block_names_its_file_and_key(change, key, detail) -> None:
    spec = _g1()
    bad = replace(spec, locomotion={**spec.locomotion, **change})
    with pytest.raises(ConfigError) as info:
        walker_settings(bad)
    assert info.value.source == "my_tasks.yaml" and detail in str(info.value)
    if key:
        assert info.value.key == f"tasks.humanoid_locomotion_g1.{key}"


def test_a_missing_course_key_names_the_block() -> None:
    spec = _g1()
    bad = replace(spec, locomotion={k: v for k, v in spec.locomotion.items() if k != "dwell_s"})
    with pytest.raises(ConfigError, match=r"my_tasks.yaml.*tasks.humanoid_locomotion_g1.locomotion.dwell_s"):
        walker_settings(bad)


def test_a_task_without_a_block_is_not_a_walker_task() -> None:
    spec = load_catalog().get("hopper_courier")
    with pytest.raises(ConfigError, match="no locomotion block"):
        walker_settings(spec)
