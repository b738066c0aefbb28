"""Evaluation-sweep cells: keys that change with every input that changes what is measured, and their records."""

import pytest

from econmotor.analysis.eval_sweep import EvalCell, plan_eval_sweep, policy_fingerprint
from econmotor.config.datapacks import parse_datapack
from econmotor.errors import ConfigError
from econmotor.motor_backend.run_dir import REPORT_EVAL_SEED_OFFSET

TASK, POLICY = "humanoid_locomotion_g1", "holosoma:g1_29dof/ppo"
STRESS = parse_datapack({"id": "stress", "domain_randomization": {"payload_kg_range": [0.0, 3.0]}})


def keys(*args, **kwargs) -> list[str]:
    return [c.key for c in plan_eval_sweep(TASK, "holosoma", *args, **kwargs)]


def test_one_cell_per_speed_datapacks_and_seed_each_with_its_own_key():
    cells = plan_eval_sweep(TASK, "holosoma", POLICY, [0.4, 0.6], [[], [STRESS]], [0, 1], eval_episodes=4)
    assert [(c.command_speed_m_per_s, c.datapack_ids, c.seed) for c in cells] == [
        (v, d, s) for v in (0.4, 0.6) for d in ((), ("stress",)) for s in (0, 1)]
    assert len({c.key for c in cells}) == 8 and all(isinstance(c, EvalCell) for c in cells)
    assert keys(POLICY, [0.4, 0.6], [[], [STRESS]], [0, 1], eval_episodes=4) == [c.key for c in cells]


def test_the_key_changes_with_speed_policy_episodes_and_measured_options():
    base = keys(POLICY, [0.4], [[]], [0])
    assert keys(POLICY, [0.5], [[]], [0]) != base
    assert keys("holosoma:g1_29dof/fastsac", [0.4], [[]], [0]) != base
    assert keys(POLICY, [0.4], [[]], [0], eval_episodes=6) != base
    assert keys(POLICY, [0.4], [[]], [0], eval_options={"eval_episode_length_s": 8.0}) != base
    assert keys(POLICY, [None], [[]], [0]) != base  # the catalog's speed is a cell of its own


def test_a_policy_file_is_keyed_by_its_content(tmp_path):
    path = tmp_path / "walker.onnx"
    path.write_bytes(b"one")
    first = keys(str(path), [0.4], [[]], [0])
    assert policy_fingerprint(str(path))[0] == str(path.resolve())
    path.write_bytes(b"two")
    assert keys(str(path), [0.4], [[]], [0]) != first
    assert policy_fingerprint(POLICY) == (POLICY, "")


def test_the_run_records_its_speed_and_evaluation_seed():
    (cell,) = plan_eval_sweep(TASK, "holosoma", POLICY, [0.8], [[]], [3])
    config = cell.run_config()
    assert config["commanded_speed_m_per_s"] == 0.8 and config["cell_key"] == cell.key
    assert config["eval_seed"] == 3 + REPORT_EVAL_SEED_OFFSET
    fields = cell.start_fields()
    assert fields["seed"] == 3 and fields["policy_path"] == POLICY and fields["objective"].name == "default"
    assert cell.run_kind == "eval" and cell.mean_j([]) is None


@pytest.mark.parametrize(("speeds", "backend", "words"), [
    ([0.0], "holosoma", "finite speed > 0"),
    ([float("nan")], "holosoma", "finite speed > 0"),
    ([0.5], "dishwashing", "walks no course at a commanded speed"),
    ([0.5, 0.5], "holosoma", "repeats a cell"),
    ([], "holosoma", "at least one speed"),
])
def test_bad_grids_are_refused(speeds, backend, words):
    with pytest.raises(ConfigError, match=words):
        plan_eval_sweep(TASK, backend, POLICY, speeds, [[]], [0])
