import pytest

from econmotor.config.task_economics import TaskEconomics
from econmotor.errors import UnknownNameError
from econmotor.motor_backend import known_backends, make_motor_backend, register_motor_backend
from econmotor.motor_backend.base import aggregate_raw, summarize_episodes


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
