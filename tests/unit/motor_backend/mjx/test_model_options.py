"""A task's ``model_options``: validated at load, applied to the model MJX runs (and the C side)."""

from __future__ import annotations

import mujoco
import pytest

from econmotor.errors import ConfigError
from econmotor.motor_backend.mjx.assets import load_model, robot_spec
from econmotor.motor_backend.mjx.env import GymCourierEnv
from econmotor.motor_backend.mjx.humanoid_env import HumanoidWalkerEnv
from econmotor.motor_backend.mjx.settings import parse_mjx_settings
from econmotor.tasks import load_catalog

from .conftest import catalog_with_mjx_entry


def with_options(task_id: str, options):
    return catalog_with_mjx_entry(task_id, "my_mjx.yaml", model_options=options)


def geoms_that_collide(model: mujoco.MjModel) -> set[str]:
    return {mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, g) for g in range(model.ngeom)
            if model.geom_contype[g] or model.geom_conaffinity[g]}


def test_the_catalog_runs_every_courier_as_brax_does_on_mjx():
    catalog = load_catalog()
    for task_id in catalog.ids("mjx"):
        if catalog.get(task_id).backends["mjx"].get("inherit") == "locomotion":
            env = HumanoidWalkerEnv(task_id, catalog=catalog)  # feet-only contacts from its robot card
            assert geoms_that_collide(env.mj_model) - {"floor"} == set(env.card.foot_geoms)
            assert env.mj_model.opt.iterations <= 4 and env.mj_model.opt.ls_iterations <= 8
            continue
        env = GymCourierEnv(task_id, catalog=catalog)
        opt = env.mj_model.opt
        assert opt.integrator == mujoco.mjtIntegrator.mjINT_EULER, task_id
        assert opt.solver == mujoco.mjtSolver.mjSOL_NEWTON and opt.iterations <= 4 and opt.ls_iterations <= 8
        assert "floor" in geoms_that_collide(env.mj_model)
        assert geoms_that_collide(env.mj_model) - {"floor"} == set(env.settings.model_options["contact_geoms"])
    humanoid = GymCourierEnv("humanoid_courier", catalog=catalog).mj_model
    assert humanoid.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_EULERDAMP


def test_without_options_the_model_is_gymnasiums_with_a_solver_mjx_runs():
    spec = robot_spec("Humanoid-v5", {}, "test")
    model, original = load_model(spec), mujoco.MjModel.from_xml_path(spec.xml_path)
    assert original.opt.solver == mujoco.mjtSolver.mjSOL_PGS and model.opt.solver == mujoco.mjtSolver.mjSOL_NEWTON
    assert model.opt.integrator == original.opt.integrator == mujoco.mjtIntegrator.mjINT_RK4
    assert model.opt.iterations == original.opt.iterations
    assert geoms_that_collide(model) == geoms_that_collide(original)
    damped = load_model(spec, {"eulerdamp": False})
    assert load_model(spec, {"eulerdamp": True}).opt.disableflags == model.opt.disableflags != damped.opt.disableflags


@pytest.mark.parametrize(("options", "match"), [
    ({"integrator": "rk5"}, r"my_mjx.yaml.*model_options.integrator.*allowed: euler, implicitfast, rk4"),
    ({"iterations": 0}, r"my_mjx.yaml.*model_options.iterations"),
    ({"ls_iterations": "many"}, r"my_mjx.yaml.*model_options.ls_iterations"),
    ({"eulerdamp": "no"}, r"my_mjx.yaml.*model_options.eulerdamp.*true or false"),
    ({"contact_geoms": []}, r"my_mjx.yaml.*model_options.contact_geoms.*non-empty list"),
    ({"timestep": 0.01}, r"my_mjx.yaml.*model_options.*timestep"),
    ("euler", r"my_mjx.yaml.*model_options"),
])
def test_bad_model_options_are_config_errors_naming_the_file_and_key(options, match):
    spec = with_options("hopper_courier", options).get("hopper_courier")
    with pytest.raises(ConfigError, match=match):
        parse_mjx_settings(spec)


def test_an_unknown_contact_geom_names_the_geoms_there_are():
    catalog = with_options("hopper_courier", {"contact_geoms": ["foot"]})
    with pytest.raises(ConfigError, match=r"my_mjx.yaml.*contact_geoms.*unknown geom 'foot'.*foot_geom, leg_geom"):
        GymCourierEnv("hopper_courier", catalog=catalog)
