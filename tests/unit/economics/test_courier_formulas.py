"""The courier formulas (economics/courier_formulas.py) on hand-computed cases, in Python floats and NumPy.

Every figure below is worked out by hand from the module docstring's formulas, not read back from the
code: a constant-torque case for energy, a back-and-forth walk for units, the tilt band for risk.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from econmotor.economics import courier_formulas as cf

CONSTANTS = cf.MeterConstants(leg_distance_m=10.0, drivetrain_efficiency=0.8, idle_power_w=50.0, dt_s=0.02,
                              tilt_margin_rad=0.1, fall_tilt_rad=0.5)


@pytest.mark.parametrize("xp", [cf.PY, np], ids=["py", "numpy"])
def test_mechanical_power_is_the_sum_of_absolute_force_times_velocity(xp):
    forces, velocities = [2.0, -3.0, 0.5], [1.5, 2.0, -4.0]
    # |2 * 1.5| + |-3 * 2| + |0.5 * -4| = 3 + 6 + 2 = 11 W
    args = (forces, velocities) if xp is cf.PY else (np.array(forces), np.array(velocities))
    assert float(cf.mechanical_power_w(*args, xp)) == pytest.approx(11.0)


def test_constant_torque_energy_over_an_hour_by_hand():
    # 10 N m at 2 rad/s = 20 W mechanical; 20 / 0.8 + 50 idle = 75 W electrical; 3600 steps of 1 s = 75 Wh
    mech = cf.mechanical_power_w([10.0], [2.0], cf.PY)
    step_wh = cf.electrical_energy_wh(mech, 0.8, 50.0, 1.0)
    assert step_wh == pytest.approx(75.0 / 3600.0)
    assert cf.electrical_energy_wh(0.0, 0.8, 0.0, 1.0) == 0.0


def _namespaces() -> list:
    import jax.numpy as jnp
    torch = pytest.importorskip("torch")
    from econmotor.motor_backend.holosoma.econ_formulas import torch_namespace

    return [pytest.param((np, np.asarray), id="numpy"), pytest.param((jnp, jnp.asarray), id="jax"),
            pytest.param((torch_namespace(), lambda a: torch.as_tensor(a, dtype=torch.float64)), id="torch")]


@pytest.mark.parametrize("namespace", _namespaces())
def test_one_joint_with_winding_heat_by_hand(namespace):
    xp, array = namespace
    # one joint, 10 N m at 2 rad/s, k = 0.1 W/(N m)^2: 20 W mechanical / 0.8 = 25 W, heat 0.1 * 10^2 = 10 W,
    # idle 50 W: 85 W electrical; over 36 s, 0.85 Wh
    tau, qd, k = array([10.0]), array([2.0]), array([0.1])
    mech, heat = cf.mechanical_power_w(tau, qd, xp), cf.winding_heat_w(tau, k, xp)
    assert (float(mech), float(heat)) == (pytest.approx(20.0), pytest.approx(10.0))
    assert float(cf.electrical_power_w(mech, 0.8, 50.0, heat)) == pytest.approx(85.0)
    assert float(cf.electrical_energy_wh(mech, 0.8, 50.0, 36.0, heat)) == pytest.approx(0.85)
    # holding the same torque without moving: no mechanical power, the heat and the idle draw remain
    held = cf.mechanical_power_w(tau, array([0.0]), xp)
    assert float(cf.electrical_power_w(held, 0.8, 50.0, heat)) == pytest.approx(60.0)
    # the sign of the torque does not matter; two joints add
    two = cf.winding_heat_w(array([[-10.0, 3.0]]), array([0.1, 0.5]), xp)
    assert float(two[0]) == pytest.approx(10.0 + 4.5)
    # the inverse recovers the mechanical power from the electrical
    assert float(cf.mechanical_from_electrical_w(85.0, 0.8, 50.0, 10.0)) == pytest.approx(20.0)


def test_the_meter_step_adds_the_windings_heat_to_the_energy():
    sums = cf.MeterSums()
    cf.meter_step(sums, cf.StepReading(x_m=0.0, mechanical_w=20.0, tilt_rad=0.0, fell=False, heat_w=10.0),
                  CONSTANTS, cf.PY)
    # (20 / 0.8 + 10 + 50) W over 0.02 s
    assert sums.energy_wh == pytest.approx(85.0 * 0.02 / 3600.0)


@pytest.mark.parametrize("xp", [cf.PY, np], ids=["py", "numpy"])
def test_units_count_the_forward_high_water_mark_only(xp):
    best, gained = cf.forward_units(0.0, 4.0, 10.0, xp)
    assert (float(best), float(gained)) == (4.0, pytest.approx(0.4))
    best, gained = cf.forward_units(best, 1.0, 10.0, xp)  # walking back earns nothing
    assert (float(best), float(gained)) == (4.0, 0.0)
    best, gained = cf.forward_units(best, 9.0, 10.0, xp)
    assert (float(best), float(gained)) == (9.0, pytest.approx(0.5))


@pytest.mark.parametrize("xp", [cf.PY, np], ids=["py", "numpy"])
def test_tilt_risk_is_zero_below_the_margin_one_past_the_fall_tilt_and_linear_between(xp):
    assert float(cf.tilt_risk(0.05, 0.1, 0.5, xp)) == 0.0
    assert float(cf.tilt_risk(0.3, 0.1, 0.5, xp)) == pytest.approx(0.5)
    assert float(cf.tilt_risk(0.2, 0.1, 0.5, xp)) == pytest.approx(0.25)
    assert float(cf.tilt_risk(0.9, 0.1, 0.5, xp)) == 1.0


def test_novelty_cells_and_bonus():
    assert np.array_equal(cf.novelty_cell(np.array([0.49, -0.01, 1.0]), 0.5, np), [0.0, -1.0, 2.0])
    assert cf.novelty_bonus(4) == pytest.approx(0.5) and cf.novelty_bonus(1) == 1.0


def test_py_namespace_helpers_behave_like_numpys():
    assert cf.PY.where(True, 1, 2) == 1 and cf.PY.where(False, 1, 2) == 2
    assert (cf.PY.clip(-1.0, 0.0, 1.0), cf.PY.clip(0.5, 0.0, 1.0), cf.PY.clip(2.0, 0.0, 1.0)) == (0.0, 0.5, 1.0)
    assert cf.PY.sum([1.0, 2.5]) == 3.5 and cf.PY.sum([]) == 0.0
    assert cf.safe_div(3.0, 0.0, cf.PY) == 0.0 and cf.safe_div(3.0, 2.0, cf.PY) == 1.5
    assert float(cf.safe_div(np.float64(3.0), np.float64(-1.0), np)) == 0.0


def step(x, mech, tilt, fell=False, novelty=0.0, pose=0.0):
    return cf.StepReading(x_m=x, mechanical_w=mech, tilt_rad=tilt, fell=fell, novelty_bonus=novelty,
                          pose_similarity=pose)


def test_three_metered_steps_by_hand():
    sums = cf.MeterSums(best_x=1.0)
    for reading in (step(3.0, 40.0, 0.0, novelty=1.0, pose=0.5), step(2.0, 0.0, 0.3, novelty=0.5),
                    step(6.0, 80.0, 0.6, fell=True, pose=0.25)):
        cf.meter_step(sums, reading, CONSTANTS, cf.PY)
    assert sums.steps == 3 and sums.best_x == 6.0
    assert sums.units == pytest.approx(0.5)  # 1 m -> 6 m forward, in 10 m legs
    assert sums.errors == 1.0
    # (40/0.8 + 50) + (0 + 50) + (80/0.8 + 50) = 100 + 50 + 150 = 300 W over 0.02 s steps
    assert sums.energy_wh == pytest.approx(300.0 * 0.02 / 3600.0)
    assert sums.risk_sum == pytest.approx(0.0 + 0.5 + 1.0)
    assert (sums.novelty_sum, sums.pose_sum) == (1.5, 0.75)
    m = cf.running_metrics(sums, CONSTANTS.dt_s, cf.PY)
    assert m.mpl_per_hour == pytest.approx(0.5 / (3 * 0.02 / 3600.0))
    assert m.error_rate == pytest.approx(1.0 / 1.5)
    assert m.energy_kwh == pytest.approx(sums.energy_wh / 1000.0)
    assert (m.risk_score, m.novelty_score, m.pose_tracking) == (pytest.approx(0.5), pytest.approx(0.5), 0.75)
    zero = cf.running_metrics(cf.MeterSums(), CONSTANTS.dt_s, cf.PY)
    assert tuple(zero) == (0.0,) * len(cf.RUNNING_METRIC_KEYS)


def test_overlay_potential_is_the_weighted_sum_of_the_running_metrics():
    factors = cf.overlay_factors({"mpl_per_hour": 2.0, "error_rate": -3.0, "energy_kwh": -5.0, "risk_score": -7.0,
                                  "novelty_score": 11.0, "pose_tracking": 13.0}, {"mpl_per_hour": 4.0})
    assert factors == {"mpl_per_hour": 0.5, "error_rate": -3.0, "energy_kwh": -5.0, "risk_score": -7.0,
                       "novelty_score": 11.0, "pose_tracking": 13.0}
    coefficients = cf.overlay_coefficients(factors, CONSTANTS.dt_s)
    assert coefficients == (0.5 * 3600.0 / 0.02, -7.0, 11.0, -3.0, -5.0 / 1000.0, 13.0)
    sums = cf.MeterSums(steps=4, units=0.3, errors=1.0, energy_wh=2.0, risk_sum=0.8, novelty_sum=1.2, pose_sum=0.4)
    m = cf.running_metrics(sums, CONSTANTS.dt_s, cf.PY)
    expected = sum(factors[k] * getattr(m, k) for k in cf.RUNNING_METRIC_KEYS)
    assert cf.overlay_potential(sums, coefficients, cf.PY) == pytest.approx(expected)
    assert cf.overlay_potential(cf.MeterSums(), coefficients, cf.PY) == 0.0
    assert cf.overlay_coefficients({}, 1.0) == (0.0,) * 6


def test_episode_metric_of_each_overlay_key():
    episode = {"units_completed": 3.0, "errors": 1.0, "episode_length_s": 1800.0, "energy_wh": 250.0,
               "risk_score": 0.2}
    assert cf.episode_metric(episode, "mpl_per_hour") == pytest.approx(6.0)
    assert cf.episode_metric(episode, "error_rate") == pytest.approx(0.25)
    assert cf.episode_metric(episode, "energy_kwh") == pytest.approx(0.25)
    assert cf.episode_metric(episode, "risk_score") == 0.2
    assert cf.episode_metric(episode, "novelty_score") == 0.0
    empty = {"units_completed": 0.0, "errors": 0.0, "episode_length_s": 0.0, "energy_wh": 0.0}
    assert cf.episode_metric(empty, "mpl_per_hour") == 0.0 and cf.episode_metric(empty, "error_rate") == 0.0
    assert math.isclose(cf.SECONDS_PER_HOUR, 3600.0) and cf.WH_PER_KWH == 1000.0


def test_batched_power_sums_each_env_over_its_own_dofs():
    forces = np.array([[1.0, -2.0], [3.0, 0.0]])
    velocities = np.array([[2.0, 1.0], [-1.0, 5.0]])
    assert np.array_equal(cf.mechanical_power_w(forces, velocities, np), [4.0, 3.0])  # |2| + |-2|, |-3| + 0


def test_errors_accumulate_over_steps_and_small_denominators_still_divide():
    sums = cf.MeterSums()
    for fell in (True, False, True):  # under vmap an env's episode sums go on after a fall until reset
        cf.meter_step(sums, step(0.0, 0.0, 0.0, fell=fell), CONSTANTS, cf.PY)
    assert sums.errors == 2.0
    assert cf.safe_div(3.0, 0.5, cf.PY) == 6.0


def test_a_fall_takes_an_episodes_rate_over_its_whole_limit() -> None:
    """J's legs per hour of an episode that fell are over its time limit: walking one leg fast and falling
    before the dwell must not score more than finishing the course (it did while a fall ended the clock)."""
    from econmotor.config.objective_profile import ObjectiveVector
    from econmotor.motor_backend.results import summarize_episodes
    from econmotor.objectives.loader import objective_from_vector, objective_j
    from econmotor.tasks import get_task

    assert cf.rate_length_s(17.0, 240.0, True, np) == 240.0
    assert cf.rate_length_s(17.0, 240.0, False, np) == 17.0
    np.testing.assert_array_equal(cf.rate_length_s(np.array([17.0, 300.0]), 240.0, np.array([True, True]), np),
                                  [240.0, 300.0])
    economics = get_task("humanoid_locomotion_g1").economics
    objective = objective_from_vector(ObjectiveVector.from_preset("energy_saver"), "energy_saver")
    base = {"units_completed": 1.0, "units_attempted": 2.0, "errors": 1.0, "episode_length_s": 17.0,
            "energy_wh": 1.0, "risk_score": 0.0, "novelty_score": 0.0, "termination_reason": "fall"}
    finished = {**base, "units_completed": 3.0, "units_attempted": 3.0, "errors": 0.0, "episode_length_s": 116.0,
                "energy_wh": 6.8, "termination_reason": "course_done", "episode_limit_s": 240.0}
    js = {}
    for name, raw in (("fell, limit recorded", {**base, "episode_limit_s": 240.0}), ("fell, no limit", base),
                      ("finished", finished)):
        [summary] = summarize_episodes([raw], economics)[2]
        js[name] = objective_j(objective, summary, economics)
    assert js["fell, limit recorded"] < js["finished"] < js["fell, no limit"]
    [summary] = summarize_episodes([{**base, "episode_limit_s": 240.0}], economics)[2]
    assert summary["mpl_episode"] == pytest.approx(3600.0 / 240.0)
    assert summary["mpl_units_per_hour"] == pytest.approx(3600.0 / 17.0)  # the legs/h of the time it ran stay
