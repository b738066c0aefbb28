import pytest

from econmotor.errors import ConfigError, UnknownNameError
from econmotor.tasks import get_task, load_catalog

USER_TASK = """\
tasks:
  folding:
    unit: "folded shirt"
    economics:
      wage_human_usd_per_hour: {value: 20.0, source: "local wage survey"}
      mp_human_units_per_hour: {value: 40.0, unit: "units/h", source: "time study"}
    backends:
      dishwashing: {econ_preset: toy}
"""


def test_shipped_tasks_have_sources_for_every_number():
    catalog = load_catalog()
    assert "dishwashing" in catalog and "dishwashing_realistic" in catalog
    for spec in catalog:
        for row in spec.economics.parameters():
            assert row["source"] and row["source"] != "econmotor default", (spec.task_id, row)
            assert row["unit"]


def test_dishwashing_economics_match_econ_context_defaults():
    econ = get_task("dishwashing").economics
    assert (econ.wage_human_usd_per_hour, econ.mp_human_units_per_hour, econ.value_per_unit) == (18.0, 60.0, 0.30)
    # the workcell's energy is a UR5e-class arm's 200 W typical power over a 37.5 s attempt (1.6/min)
    assert get_task("dishwashing_realistic").backend_entry("dishwashing") == {
        "econ_preset": "realistic", "econ_overrides": {"energy_Wh_per_attempt": 2.08}}
    assert 200 * 37.5 / 3600 == pytest.approx(2.08, abs=0.005)


def test_user_file_extends_catalog(tmp_path):
    path = tmp_path / "mine.yaml"
    path.write_text(USER_TASK)
    catalog = load_catalog([path])
    spec = catalog.get("folding")
    assert spec.economics.value_per_unit == pytest.approx(0.5)
    assert spec.economics.sources["wage_human_usd_per_hour"] == "local wage survey"
    assert "folding" in catalog.ids("dishwashing") and "folding" not in catalog.ids("holosoma")


def test_unknown_task_lists_known():
    with pytest.raises(UnknownNameError, match="known task ids: .*dishwashing"):
        get_task("dishwasher")
    with pytest.raises(UnknownNameError, match="did you mean 'dishwashing'"):
        get_task("dishwashin")


def test_backend_entry_missing_names_backends():
    with pytest.raises(ConfigError, match="no entry for backend 'holosoma'"):
        get_task("dishwashing").backend_entry("holosoma")


@pytest.mark.parametrize("replace, key", [
    ('{value: -20.0, source: "x"}', "tasks.folding.economics.wage_human_usd_per_hour.value"),
    ('{value: 20.0}', "tasks.folding.economics.wage_human_usd_per_hour.source"),
    ('{value: 20.0, unit: "EUR/h", source: "x"}', "tasks.folding.economics.wage_human_usd_per_hour.unit"),
    ('{value: .nan, source: "x"}', "tasks.folding.economics.wage_human_usd_per_hour.value"),
])
def test_bad_user_task_files(tmp_path, replace, key):
    text = USER_TASK.replace('{value: 20.0, source: "local wage survey"}', replace)
    path = tmp_path / "bad.yaml"
    path.write_text(text)
    with pytest.raises(ConfigError) as info:
        load_catalog([path])
    assert info.value.key == key and str(path) in str(info.value)


def test_unknown_task_key_with_suggestion(tmp_path):
    path = tmp_path / "bad.yaml"
    path.write_text(USER_TASK.replace('unit: "folded shirt"', 'unit: "folded shirt"\n    descripton: x'))
    with pytest.raises(ConfigError, match="did you mean 'description'"):
        load_catalog([path])


def test_shipped_example_user_file_loads():
    from pathlib import Path

    path = Path(__file__).parents[3] / "configs" / "tasks" / "example_user_tasks.yaml"
    spec = load_catalog([path]).get("dishwashing_hotel_eu")
    assert spec.economics.value_per_unit == pytest.approx(24.0 / 70.0)


LOCOMOTION = sorted(spec.task_id for spec in load_catalog() if "locomotion" in spec.tags)


@pytest.mark.parametrize("task_id", LOCOMOTION)
def test_a_locomotion_task_calls_its_errors_falls(task_id):
    """The report's sentences come from the task's own ``error_name``: the hopper's and the G1's alike."""
    assert get_task(task_id).acceptance.error_name == "fall"


def test_the_g1_report_says_falls_and_keeps_the_humans_rate_as_its_limit():
    from econmotor.economics.pricing import price_task
    from econmotor.economics.uncertainty import judge

    task = get_task("humanoid_locomotion_g1")
    assert {"humanoid_locomotion_g1", "humanoid_locomotion_t1", "hopper_courier"} <= set(LOCOMOTION)
    assert task.acceptance.max_error_rate == task.economics.error_rate_human == 0.01  # the default rule
    assert task.acceptance.sources["max_error_rate"] == "default: the human's error rate (error_rate_human)"
    episodes = [{"units_completed": 3.0, "errors": 0.0, "episode_length_s": 120.0, "energy_wh": 4.0}] * 120
    point = price_task(task.economics, 90.0, 0.0, 0.12)
    _, verdict = judge(task.economics, task.acceptance, task.unit, episodes, point)
    text = verdict.checks[1]["text"]
    assert text.startswith("falls in none of 120 episodes (0 in 360 attempted); 95% upper bound on the fall rate")
    assert "error" not in text
