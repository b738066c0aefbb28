import pytest

from econmotor.config.task_economics import TaskEconomics
from econmotor.errors import UnknownNameError
from econmotor.motor_backend import known_backends, make_motor_backend, register_motor_backend
from econmotor.motor_backend.results import (
    PROVENANCE_KEY,
    EvalProvenance,
    MotorEvalResult,
    aggregate_raw,
    evaluation_result,
    mean_power_w,
    summarize_episodes,
    walking_speed_m_per_s,
)


def test_known_backends_include_the_three_builtin():
    assert {"mujoco", "dishwashing", "holosoma"} <= set(known_backends())


def test_unknown_backend_lists_known():
    with pytest.raises(UnknownNameError) as info:
        make_motor_backend("isaac")
    assert "dishwashing" in str(info.value) and "mujoco" in str(info.value)


def test_register_requires_module_colon_class():
    with pytest.raises(ValueError):
        register_motor_backend("x", "no_colon")


def test_summarize_episodes_is_ratio_of_sums():
    eps = [
        {"units_completed": 10, "errors": 0, "episode_length_s": 600, "energy_wh": 5, "return": 1.0},
        {"units_completed": 20, "errors": 10, "episode_length_s": 1200, "energy_wh": 15, "return": 3.0,
         "termination_reason": "fall"},
    ]
    raw, econ, summaries = summarize_episodes(eps, TaskEconomics())
    assert raw == {"num_episodes": 2.0, "units_completed": 30.0, "errors": 10.0, "episode_length_s": 1800.0,
                   "energy_wh": 20.0, "return": 2.0}
    assert econ["mpl_units_per_hour"] == pytest.approx(60.0)
    assert econ["error_rate"] == pytest.approx(10 / 40)
    assert summaries[0]["mpl_episode"] == pytest.approx(60.0)
    assert summaries[1]["error_rate_episode"] == pytest.approx(1 / 3)
    assert summaries[0]["termination_reason"] == "max_steps"
    assert summaries[1]["termination_reason"] == "fall"
    assert aggregate_raw([]) == {"num_episodes": 0.0}


def test_an_evaluations_provenance_travels_in_its_config_and_survives_a_rebuild(tmp_path):
    """A sequential evaluation rebuilds its result from the episodes it kept and the first result's config:
    the provenance comes along, and ``evaluation.json`` records it."""
    import json

    eps = [{"units_completed": 2, "errors": 0, "episode_length_s": 60.0, "energy_wh": 1.0,
            "achieved_speed_m_per_s": 0.5, "walking_s": 30.0},
           {"units_completed": 1, "errors": 1, "episode_length_s": 60.0, "energy_wh": 2.0,
            "achieved_speed_m_per_s": 0.8, "walking_s": 10.0}]
    provenance = EvalProvenance(evaluator="sim2sim", figures_from="a course", commanded_speed_m_per_s=1.0,
                                achieved_speed_m_per_s=walking_speed_m_per_s(eps),
                                mean_power_w=mean_power_w(aggregate_raw(eps)))
    first = evaluation_result("b", "p", "t", eps, TaskEconomics(), {"seed": 3}, tmp_path, provenance)
    assert first.provenance == provenance and first.config[PROVENANCE_KEY] == provenance.to_dict()
    assert provenance.achieved_speed_m_per_s == pytest.approx((0.5 * 30 + 0.8 * 10) / 40)
    assert provenance.mean_power_w == pytest.approx(3.0 / (120 / 3600))
    rebuilt = evaluation_result("b", "p", "t", eps[:1], TaskEconomics(), {**first.config, "sequential": {}})
    assert rebuilt.provenance == provenance
    saved = json.loads((tmp_path / "evaluation.json").read_text())
    assert saved["config"][PROVENANCE_KEY]["evaluator"] == "sim2sim"


def test_a_result_without_provenance_says_so_and_episodes_without_a_course_have_no_speed():
    result = MotorEvalResult("p", "t", "b", {}, {})
    assert result.provenance == EvalProvenance() and result.provenance.evaluator == "unknown"
    assert walking_speed_m_per_s([{"units_completed": 1}]) is None and mean_power_w({}) is None
