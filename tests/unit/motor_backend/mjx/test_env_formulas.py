"""One definition per courier formula: the mujoco (NumPy / Python-float) and mjx (JAX) paths call
the same functions of ``econmotor.economics.courier_formulas``; the catalog shares the metering."""

from __future__ import annotations

from dataclasses import replace

import gymnasium as gym
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from econmotor.economics import courier_formulas as cf
from econmotor.errors import ConfigError
from econmotor.motor_backend.datapacks import DatapackConfig
from econmotor.motor_backend.mjx import env as mjx_env
from econmotor.motor_backend.mjx.assets import ROBOTS, robot_spec
from econmotor.motor_backend.mjx.settings import INHERITED_KEYS, parse_mjx_settings
from econmotor.motor_backend.mujoco import metering, overlay
from econmotor.motor_backend.mujoco.settings import parse_mujoco_settings
from econmotor.tasks import load_catalog

FORMULAS = ("high_water_units", "step_energy_wh", "planar_tilt_rad", "free_tilt_rad",
            "tilt_risk", "novelty_bonus", "novelty_cell", "running_metrics")


def test_the_mujoco_meter_and_overlay_use_the_shared_functions():
    for name in FORMULAS:
        assert getattr(metering, name) is getattr(cf, name), name
    for name in ("overlay_potential", "potential_coefficients", "overlay_factors"):
        assert getattr(overlay, name) is getattr(cf, name), name
    assert overlay.episode_metric is cf.episode_metric
    assert metering.RUNNING_METRIC_KEYS is cf.RUNNING_METRIC_KEYS


def test_the_mjx_step_traces_through_the_shared_functions(monkeypatch, hopper):
    """Spy on the shared module while the jitted step is traced (eval_shape: no compile)."""
    calls: dict[str, list[str]] = {}
    for name in (*FORMULAS, "overlay_potential", "is_healthy"):
        original = getattr(cf, name)

        def spy(*args, _name=name, _original=original, **kwargs):
            traced = any(isinstance(a, jax.core.Tracer) for a in (*args, *vars(args[1]).values())
                         ) if _name == "overlay_potential" else any(isinstance(a, jax.core.Tracer) for a in args)
            calls.setdefault(_name, []).append(traced)
            return _original(*args, **kwargs)

        monkeypatch.setattr(cf, name, spy)
    env = hopper.env
    state = jax.eval_shape(lambda k: env.reset(k, 2), jax.random.PRNGKey(0))
    # a fresh function: a traced env.step may be cached from another test's jit
    jax.eval_shape(lambda s, a: env.step(s, a), state, jax.ShapeDtypeStruct((2, env.action_size), jnp.float32))
    expected = set(FORMULAS) - {"free_tilt_rad"} | {"overlay_potential", "is_healthy"}  # the hopper is planar
    assert expected <= set(calls)
    assert all(all(calls[name]) for name in expected), calls  # called on traced JAX arrays


@pytest.mark.parametrize("xp", ["py", "np", "jnp"])
def test_formulas_give_the_same_numbers_in_every_namespace(xp):
    space = {"py": cf.PY, "np": np, "jnp": jnp}[xp]
    conv = {"py": float, "np": np.float64, "jnp": lambda v: jnp.asarray(v, jnp.float32)}[xp]
    gain, best = cf.high_water_units(conv(1.25), conv(1.0), 10.0, space)
    assert float(gain) == pytest.approx(0.025) and float(best) == pytest.approx(1.25)
    gain, best = cf.high_water_units(conv(0.5), conv(1.0), 10.0, space)
    assert float(gain) == 0.0 and float(best) == 1.0
    f, v = [2.0, -3.0, 0.5], [1.0, 2.0, -4.0]
    args = (f, v) if xp == "py" else (space.asarray(f), space.asarray(v))
    wh = cf.step_energy_wh(*args, 1 / 0.5, 20.0, 0.008, space)  # |2*1| + |-3*2| + |0.5*-4| = 10 W mechanical
    assert float(wh) == pytest.approx((10 / 0.5 + 20) * 0.008 / 3600, rel=1e-6)
    assert float(cf.tilt_risk(cf.planar_tilt_rad(conv(-0.15), space), 0.1, 0.1, space)) == pytest.approx(0.5, rel=1e-5)
    assert float(cf.free_tilt_rad(conv(np.sin(0.3)), conv(0.0), space)) == pytest.approx(0.6, rel=1e-5)
    m = cf.running_metrics(conv(10.0), conv(0.5), conv(1.0), conv(2.0), conv(3.0), conv(4.0), 0.0, 0.01, space)
    assert [float(x) for x in m] == pytest.approx([0.5 * 3600 / 0.1, 1 / 1.5, 0.002, 0.3, 0.4, 0.0], rel=1e-6)
    zero = cf.running_metrics(conv(0.0), conv(0.0), conv(0.0), conv(0.0), conv(0.0), conv(0.0), 0.0, 0.01, space)
    assert [float(x) for x in zero] == [0.0] * 6  # no division by zero at the episode's start


@pytest.mark.parametrize("env_id", list(ROBOTS))
def test_the_fall_rule_is_gymnasiums_healthy_check(env_id):
    """cf.is_healthy (the mjx fall) agrees with the Gymnasium env's own is_healthy on random states."""
    env = gym.make(env_id).unwrapped
    spec = robot_spec(env_id)
    rule = cf.healthy_rule(spec.robot, spec.params)
    rng = np.random.default_rng(0)
    env.reset(seed=0)
    agree = {True: 0, False: 0}
    for _ in range(300):
        qpos = env.init_qpos + rng.normal(0, 0.4, env.model.nq)
        qvel = rng.normal(0, 60, env.model.nv)
        qpos[rule.z_index] = rng.uniform(rule.z_range[0] - 0.5, min(rule.z_range[1], 3.0) + 0.5)
        env.set_state(qpos, qvel)
        expected = bool(env.is_healthy)
        assert bool(cf.is_healthy(rule, qpos, qvel, np)) == expected
        assert bool(cf.is_healthy(rule, jnp.asarray(qpos), jnp.asarray(qvel), jnp)) == expected
        agree[expected] += 1
    assert min(agree.values()) > 20  # both outcomes were exercised


def test_mjx_catalog_entries_inherit_the_mujoco_metering():
    catalog = load_catalog()
    assert set(catalog.ids("mjx")) == {"hopper_courier", "walker_courier", "ant_courier", "humanoid_courier"}
    for task_id in catalog.ids("mjx"):
        spec = catalog.get(task_id)
        mjx_settings, mujoco_settings = parse_mjx_settings(spec), parse_mujoco_settings(spec)
        for key in INHERITED_KEYS:
            assert getattr(mjx_settings, key) == getattr(mujoco_settings, key), (task_id, key)
        assert mjx_settings.num_envs >= 1024 and mjx_settings.ppo
        assert spec.backend_source("mjx").endswith("mjx.yaml")


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
    env = mjx_env.MjxCourierEnv("hopper_courier", datapacks=[DatapackConfig(
        id="dr", domain_randomization={"friction_range": [0.5, 0.9], "mass_scale_range": [0.8, 1.2]})])
    state = jax.jit(env.reset, static_argnums=1)(jax.random.PRNGKey(0), 8)
    friction, mass = np.asarray(state.randomization["friction_scale"]), np.asarray(state.randomization["mass_scale"])
    assert friction.shape == (8,) and np.all((friction >= 0.5) & (friction <= 0.9)) and np.ptp(friction) > 0
    assert mass.shape == (8, env.mj_model.nbody) and np.all(mass[:, 0] == 1.0)
    assert np.all((mass[:, 1:] >= 0.8) & (mass[:, 1:] <= 1.2))
    model = env._randomized_model({"friction_scale": friction[0], "mass_scale": mass[0]})
    np.testing.assert_allclose(np.asarray(model.geom_friction[:, 0]), env.mj_model.geom_friction[:, 0] * friction[0],
                               rtol=1e-6)
    np.testing.assert_allclose(np.asarray(model.body_mass), env.mj_model.body_mass * mass[0], rtol=1e-6)


@pytest.mark.parametrize("task_id", ["walker_courier", "ant_courier", "humanoid_courier"])
def test_every_courier_has_the_gymnasium_layout(task_id):
    """Traced without compiling (eval_shape): obs/action sizes and bounds, control dt, metric keys."""
    env = mjx_env.MjxCourierEnv(task_id)
    gym_env = gym.make(env.settings.env_id)
    assert env.observation_size == gym_env.observation_space.shape[0]
    np.testing.assert_array_equal(env.action_low, gym_env.action_space.low)
    np.testing.assert_array_equal(env.action_high, gym_env.action_space.high)
    assert env.control_dt_s == pytest.approx(gym_env.unwrapped.dt)
    state = jax.eval_shape(lambda k: env.reset(k, 3), jax.random.PRNGKey(0))
    after = jax.eval_shape(env.step, state, jax.ShapeDtypeStruct((3, env.action_size), jnp.float32))
    assert after.obs.shape == (3, env.observation_size) and after.reward.shape == (3,)
    assert jax.tree_util.tree_structure(after) == jax.tree_util.tree_structure(state)  # scan-able
