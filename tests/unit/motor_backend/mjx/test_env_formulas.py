"""One definition per courier formula: the mujoco (Python-float) and mjx (JAX) paths call the same
functions of ``econmotor.economics.courier_formulas`` and ``motor_backend.couriers``; the catalog
shares the metering."""

from __future__ import annotations

from dataclasses import astuple, is_dataclass, replace

import gymnasium as gym
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from econmotor.config.datapacks import DatapackConfig
from econmotor.couriers import overlay, physics
from econmotor.economics import courier_formulas as cf
from econmotor.errors import ConfigError
from econmotor.locomotion.task import meter_settings, reward_terms, task_settings
from econmotor.motor_backend.mjx import env as mjx_env
from econmotor.motor_backend.mjx.settings import INHERITED_KEYS, LOCOMOTION_COURSE, parse_mjx_settings
from econmotor.motor_backend.mjx.wrappers import make_env
from econmotor.motor_backend.mujoco import metering
from econmotor.motor_backend.mujoco.settings import parse_mujoco_settings
from econmotor.motor_backend.mujoco.walker_backend import walker_train_settings
from econmotor.robots import card
from econmotor.robots import gym_couriers as robots
from econmotor.tasks import load_catalog

FORMULAS = ("meter_step", "mechanical_power_w", "novelty_bonus", "novelty_cell", "running_metrics",
            "overlay_potential")


def test_the_mujoco_meter_and_overlay_use_the_shared_functions():
    for name in FORMULAS:
        assert getattr(metering, name) is getattr(cf, name), name
    assert metering.root_tilt_rad is physics.root_tilt_rad
    assert overlay.overlay_factors is cf.overlay_factors
    assert overlay.TERM_METRICS is cf.RUNNING_METRIC_KEYS


def test_the_mjx_step_traces_through_the_shared_functions(monkeypatch, hopper):
    """Spy on the shared modules while the jitted step is traced (eval_shape: no compile)."""
    calls: dict[str, list[bool]] = {}
    spied = {cf: ("meter_step", "mechanical_power_w", "novelty_bonus", "novelty_cell", "running_metrics",
                  "overlay_potential"), robots: ("is_healthy",)}
    for module, names in spied.items():
        for name in names:
            original = getattr(module, name)

            def spy(*args, _name=name, _original=original, **kwargs):
                # a MeterSums (a plain dataclass, no pytree) by its fields
                leaves = jax.tree_util.tree_leaves([vars(a) if is_dataclass(a) else a for a in args])
                calls.setdefault(_name, []).append(any(isinstance(a, jax.core.Tracer) for a in leaves))
                return _original(*args, **kwargs)

            monkeypatch.setattr(module, name, spy)
    env = hopper.env
    state = jax.eval_shape(lambda k: env.reset(k, 2), jax.random.PRNGKey(0))
    # a fresh function: a traced env.step may be cached from another test's jit
    jax.eval_shape(lambda s, a: env.step(s, a), state, jax.ShapeDtypeStruct((2, env.action_size), jnp.float32))
    assert set(calls) == {n for names in spied.values() for n in names}
    assert all(all(traced) for traced in calls.values()), calls  # called on traced JAX arrays


def _meter_case(xp_name: str, free_root: bool):
    """One step of meter_step from hand-picked sums and state, in namespace ``xp_name``."""
    xp = {"py": cf.PY, "np": np, "jnp": jnp}[xp_name]
    conv = {"py": float, "np": np.float64, "jnp": lambda v: jnp.asarray(v, jnp.float32)}[xp_name]
    arr = (lambda v: np.asarray(v, np.float64)) if xp_name != "jnp" else (lambda v: jnp.asarray(v, jnp.float32))
    # x = 1.25 past best_x = 1.0; planar angle -0.15 (free root: qx = sin(0.15), so tilt 0.3)
    qpos = arr([1.25, 1.1, -0.15, 1.0, np.sin(0.15), 0.0, 0.0]) if free_root else arr([1.25, 1.1, -0.15])
    f, v = arr([2.0, -3.0, 0.5]), arr([1.0, 2.0, -4.0])  # |2*1| + |-3*2| + |0.5*-4| = 10 W mechanical
    if xp_name == "py":  # Python floats and lists of floats
        qpos, f, v = qpos.tolist(), f.tolist(), v.tolist()
    factors = {"mpl_per_hour": 2.0, "risk_score": -3.0, "novelty_score": 0.5, "error_rate": -4.0,
               "energy_kwh": -5.0, "pose_tracking": 0.25}
    c = cf.MeterConstants(10.0, 0.5, 20.0, 0.008, 0.1, 0.5 if free_root else 0.2)
    sums = cf.MeterSums(*(conv(x) for x in (3.0, 0.5, 1.0, 1.0, 2.0, 0.25, 1.0, 1.5)))
    fell = True if xp_name == "py" else xp.asarray(True)
    reading = cf.StepReading(qpos[0], cf.mechanical_power_w(f, v, xp), physics.root_tilt_rad(qpos, free_root, xp),
                             fell, conv(0.5), conv(0.5))
    cf.meter_step(sums, reading, c, xp)
    j = cf.overlay_potential(sums, cf.overlay_coefficients(factors, 0.008), xp)
    return [float(x) for x in (*astuple(sums), j)]


@pytest.mark.parametrize("free_root", [False, True])
@pytest.mark.parametrize("xp", ["py", "np", "jnp"])
def test_meter_step_gives_the_same_numbers_in_every_namespace(xp, free_root):
    steps, units, best_x, errors, wh, risk_sum, novelty_sum, pose_sum, j = _meter_case(xp, free_root)
    assert (steps, best_x, errors, novelty_sum, pose_sum) == pytest.approx((4.0, 1.25, 2.0, 1.5, 2.0))
    assert units == pytest.approx(0.5 + 0.025)
    assert wh == pytest.approx(2.0 + (10 / 0.5 + 20) * 0.008 / 3600, rel=1e-6)
    # (tilt - margin) / span: planar (0.15 - 0.1) / 0.1, free root (0.3 - 0.1) / 0.4
    assert risk_sum == pytest.approx(0.25 + 0.5, rel=1e-5)
    m = cf.running_metrics(cf.MeterSums(4.0, units, best_x, errors, wh, risk_sum, 1.5, 2.0), 0.008, cf.PY)
    expected_j = 2.0 * m[0] - 3.0 * m[3] + 0.5 * m[4] - 4.0 * m[1] - 5.0 * m[2] + 0.25 * m[5]  # sum_k factor_k m_k
    assert j == pytest.approx(expected_j, rel=1e-5)
    assert _meter_case(xp, free_root) == pytest.approx(_meter_case("py", free_root), rel=1e-5)


@pytest.mark.parametrize("n", [0, 1, 3, 17])
def test_mechanical_power_is_the_same_sum_in_every_namespace(n):
    """sum_j |f_j v_j|: lists of Python floats (PY), NumPy and JAX arrays agree."""
    rng = np.random.default_rng(n)
    f, v = rng.normal(size=n), rng.normal(size=n)
    expected = float(np.sum(np.abs(f * v)))
    assert cf.mechanical_power_w(f.tolist(), v.tolist(), cf.PY) == pytest.approx(expected, rel=1e-12, abs=0)
    assert type(cf.mechanical_power_w(f.tolist(), v.tolist(), cf.PY)) is float
    assert float(cf.mechanical_power_w(f, v, np)) == pytest.approx(expected, rel=1e-12, abs=0)
    assert float(cf.mechanical_power_w(jnp.asarray(f), jnp.asarray(v), jnp)) == pytest.approx(expected, rel=1e-5)


def test_running_metrics_are_zero_before_the_first_step():
    m = cf.running_metrics(cf.MeterSums(10.0, 0.5, 0.0, 1.0, 2.0, 3.0, 4.0, 0.0), 0.01, cf.PY)
    assert list(m) == pytest.approx([0.5 * 3600 / 0.1, 1 / 1.5, 0.002, 0.3, 0.4, 0.0], rel=1e-9)
    c = cf.overlay_coefficients(dict.fromkeys(cf.RUNNING_METRIC_KEYS, 1.0), 0.01)
    for xp in (cf.PY, np, jnp):
        zeros = cf.MeterSums(*(xp.asarray(0.0) if xp is not cf.PY else 0.0 for _ in range(8)))
        assert [float(x) for x in cf.running_metrics(zeros, 0.01, xp)] == [0.0] * 6  # no division by zero
        assert float(cf.overlay_potential(zeros, c, xp)) == 0.0


def test_the_per_step_formulas_are_plain_functions_of_named_quantities():
    """The public per-step formulas (the Holosoma evaluator calls them too)."""
    points = np.array([[0.3, -0.1, 1.0], [np.nan, 0.74, -0.76]])
    np.testing.assert_array_equal(cf.novelty_cell(points, 0.25, np), [[1, -1, 4], [np.nan, 2, -4]])
    np.testing.assert_array_equal(cf.novelty_cell(jnp.asarray(points), 0.25, jnp), [[1, -1, 4], [np.nan, 2, -4]])
    assert cf.forward_units(1.0, 1.25, 10.0, cf.PY) == (1.25, pytest.approx(0.025))
    assert cf.forward_units(1.25, 1.0, 10.0, cf.PY) == (1.25, 0.0)  # moving back earns nothing
    assert cf.electrical_energy_wh(10.0, 0.5, 20.0, 3600.0) == pytest.approx(40.0)
    assert cf.tilt_risk(0.15, 0.1, 0.2, cf.PY) == pytest.approx(0.5)
    assert cf.tilt_risk(0.05, 0.1, 0.2, cf.PY) == 0.0 and cf.tilt_risk(0.5, 0.1, 0.2, cf.PY) == 1.0


def test_mjx_catalog_entries_inherit_the_mujoco_metering():
    catalog = load_catalog()
    couriers = [t for t in catalog.ids("mjx") if catalog.get(t).backends["mjx"].get("inherit") == "mujoco"]
    assert set(couriers) == {"hopper_courier", "walker_courier", "ant_courier", "humanoid_courier"}
    for task_id in couriers:
        spec = catalog.get(task_id)
        mjx_settings, mujoco_settings = parse_mjx_settings(spec), parse_mujoco_settings(spec)
        for key in INHERITED_KEYS:
            assert getattr(mjx_settings, key) == getattr(mujoco_settings, key), (task_id, key)
        assert mjx_settings.num_envs >= 1024 and mjx_settings.ppo
        assert spec.backend_source("mjx").endswith("mjx.yaml")


def test_robot_couriers_inherit_the_walker_tasks_one_place():
    """The mjx couriers of the card robots take robot, meter, course and reward terms from the task's locomotion
    block, the one the holosoma and mujoco backends read."""
    catalog = load_catalog()
    robots = {t: catalog.get(t).locomotion["robot"] for t in catalog.ids("mjx")
              if catalog.get(t).backends["mjx"].get("inherit") == "locomotion"}
    assert robots == {"humanoid_locomotion_g1": "g1_29dof", "humanoid_locomotion_t1": "t1_29dof"}
    for task_id in robots:
        spec = catalog.get(task_id)
        settings, block = parse_mjx_settings(spec), spec.locomotion
        assert settings.robot == robots[task_id]
        meter = meter_settings(task_id, task_settings(spec), spec.source)  # the holosoma backend's meter
        for key, value in meter.items():  # one meter per robot: Holosoma's training terms and sim-to-sim read it
            assert getattr(settings, key) == value, (task_id, key)
        assert settings.fall_tilt_rad == card(robots[task_id]).fall_tilt_rad
        for theirs, ours in LOCOMOTION_COURSE.items():
            assert settings.course[ours] == block[theirs], (task_id, ours)
        assert settings.start_joint_noise_rad == block["sim2sim_start_joint_noise_rad"]
        assert settings.locomotion["episode_s"] == block["sim2sim_episode_s"]
        assert (settings.locomotion["weights"], settings.locomotion["params"]) == reward_terms(spec)
        assert set(settings.locomotion["weights"]) == set(walker_train_settings(spec).weights)  # one reward set


def test_an_inherited_key_written_again_is_a_config_error():
    spec = load_catalog().get("hopper_courier")
    entry = {**spec.backends["mjx"], "idle_power_w": 5.0}
    bad = replace(spec, backends={**spec.backends, "mjx": entry}, backend_sources={"mjx": "my_mjx.yaml"})
    with pytest.raises(ConfigError, match=r"my_mjx.yaml.*idle_power_w"):
        parse_mjx_settings(bad)


def test_datapacks_the_mjx_env_cannot_honour_are_config_errors():
    def pack(**dr):
        return DatapackConfig(id="p", domain_randomization=dr, source="packs/p.yaml")

    assert mjx_env.parse_mjx_randomization([pack(friction_range=[0.5, 1.0], mass_scale_range=[0.8, 1.2])]).active
    with pytest.raises(ConfigError, match=r"packs/p.yaml.*push_force_n"):
        mjx_env.parse_mjx_randomization([pack(push_force_n=10.0, push_interval_s=1.0)])
    with pytest.raises(ConfigError, match=r"terrain"):
        mjx_env.parse_mjx_randomization([pack(terrain="rough")])
    with pytest.raises(ConfigError, match=r"curriculum"):
        mjx_env.parse_mjx_randomization([DatapackConfig(id="c", curriculum={"initial_difficulty": 0.2})])


def test_friction_and_mass_are_drawn_per_env_at_reset():
    env = make_env(mjx_env.GymCourierEnv, "hopper_courier", datapacks=[DatapackConfig(
        id="dr", domain_randomization={"friction_range": [0.5, 0.9], "mass_scale_range": [0.8, 1.2]})])
    state = jax.jit(env.reset, static_argnums=1)(jax.random.PRNGKey(0), 8)
    friction, mass = np.asarray(state.randomization["friction_scale"]), np.asarray(state.randomization["mass_scale"])
    assert friction.shape == (8,) and np.all((friction >= 0.5) & (friction <= 0.9)) and np.ptp(friction) > 0
    assert mass.shape == (8, env.mj_model.nbody) and np.all(mass[:, 0] == 1.0)
    assert np.all((mass[:, 1:] >= 0.8) & (mass[:, 1:] <= 1.2))
    model = env.randomized_model({"friction_scale": friction[0], "mass_scale": mass[0]})
    np.testing.assert_allclose(np.asarray(model.geom_friction[:, 0]), env.mj_model.geom_friction[:, 0] * friction[0],
                               rtol=1e-6)
    np.testing.assert_allclose(np.asarray(model.body_mass), env.mj_model.body_mass * mass[0], rtol=1e-6)


@pytest.mark.parametrize("task_id", ["walker_courier", "ant_courier", "humanoid_courier"])
def test_every_courier_has_the_gymnasium_layout(task_id):
    """Traced without compiling (eval_shape): obs/action sizes and bounds, control dt, metric keys."""
    env = make_env(mjx_env.GymCourierEnv, task_id)
    gym_env = gym.make(env.settings.env_id)
    assert env.observation_size == gym_env.observation_space.shape[0]
    np.testing.assert_array_equal(env.action_low, gym_env.action_space.low)
    np.testing.assert_array_equal(env.action_high, gym_env.action_space.high)
    assert env.control_dt_s == pytest.approx(gym_env.unwrapped.dt)
    state = jax.eval_shape(lambda k: env.reset(k, 3), jax.random.PRNGKey(0))
    after = jax.eval_shape(env.step, state, jax.ShapeDtypeStruct((3, env.action_size), jnp.float32))
    assert after.obs.shape == (3, env.observation_size) and after.reward.shape == (3,)
    assert jax.tree_util.tree_structure(after) == jax.tree_util.tree_structure(state)  # scan-able


def test_an_overlay_term_the_mjx_env_cannot_weight_is_a_config_error():
    from econmotor.objectives import EconomicObjectiveSpec

    with pytest.raises(ConfigError, match=r"extra_weights\.pose_tracking.*mjx backend"):
        make_env(mjx_env.GymCourierEnv, "hopper_courier",
                 objective=EconomicObjectiveSpec(extra_weights={"pose_tracking": 1.0}))
