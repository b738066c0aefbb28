"""The robots of the mjx couriers: Gymnasium's own MJCF files, loaded for MJX.

The robot records (model file, Gymnasium v5 parameters, healthy rule, observation, reward and
reset facts) are the couriers' (``robots/gym_couriers.py``: :func:`robot_spec` applies a catalog
entry's ``env_kwargs``), so the mjx env's observation, action, reward and fall definitions are
the ones the ``mujoco`` backend gets from ``gymnasium.make(env_id)``, without importing
gymnasium here.

:func:`load_model` changes two kinds of options at load:

- what MJX cannot run (:data:`MJX_ADJUSTMENTS`): ``humanoid.xml`` uses the PGS constraint
  solver; MJX implements CG and Newton only, so the solver becomes Newton.
- what the task's ``model_options`` declare (``tasks/mjx.yaml``, validated by
  ``mjx/settings.py``): Gymnasium's MJCF is written for MuJoCo C, with the RK4 integrator, 50-100
  solver iterations at tolerance 1e-8 (float32 never reaches it, so a batch runs them all) and
  every capsule colliding. Brax and MuJoCo Playground run these robots on MJX with the Euler
  integrator, 1-4 solver iterations, 4-8 line-search iterations and only the feet colliding;
  on a GPU this is what makes thousands of envs fast (``benchmarks/mjx_model_options.py``).

A parity test comparing MuJoCo C with MJX applies both to the C side (:func:`apply_model_options`).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import mujoco

from econmotor.errors import ConfigError
from econmotor.motor_backend.mjx.settings import INTEGRATORS
from econmotor.robots.gym_couriers import ROBOTS, RobotSpec, robot_spec

__all__ = ["MJX_ADJUSTMENTS", "ROBOTS", "RobotSpec", "apply_model_options", "load_model", "robot_spec"]

#: what load_model changes for MJX whatever the task says (documented in the module docstring).
MJX_ADJUSTMENTS = {"opt.solver": "PGS -> Newton (MJX has CG and Newton only; humanoid.xml uses PGS)"}

#: the integrators ``model_options`` names (settings.INTEGRATORS), as MuJoCo's enum
_INTEGRATORS = {name: getattr(mujoco.mjtIntegrator, f"mjINT_{name.upper()}") for name in INTEGRATORS}


def apply_model_options(model: mujoco.MjModel, options: Mapping[str, Any], source: str = "<model_options>") -> None:
    """Set ``model``'s solver to one MJX runs and apply a task's validated ``model_options`` in place.

    ``contact_geoms`` keeps collisions for the world's geoms (the floor) and the named robot geoms;
    an unknown name is a :class:`ConfigError` naming ``source`` and the allowed geoms.
    """
    if model.opt.solver == mujoco.mjtSolver.mjSOL_PGS:
        model.opt.solver = mujoco.mjtSolver.mjSOL_NEWTON
    if "integrator" in options:
        model.opt.integrator = _INTEGRATORS[options["integrator"]]
    if "iterations" in options:
        model.opt.iterations = options["iterations"]
    if "ls_iterations" in options:
        model.opt.ls_iterations = options["ls_iterations"]
    if "eulerdamp" in options:
        flag = int(mujoco.mjtDisableBit.mjDSBL_EULERDAMP)
        model.opt.disableflags = model.opt.disableflags & ~flag if options["eulerdamp"] \
            else model.opt.disableflags | flag
    if "contact_geoms" in options:
        robot_geoms = {g: mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, g)
                       for g in range(model.ngeom) if model.geom_bodyid[g] != 0}  # id -> name (or None)
        unknown = set(options["contact_geoms"]) - set(robot_geoms.values())
        if unknown:
            raise ConfigError(source, "model_options.contact_geoms", f"unknown geom '{min(unknown)}'",
                              sorted(n for n in robot_geoms.values() if n))
        for g, name in robot_geoms.items():
            if name not in options["contact_geoms"]:
                model.geom_contype[g] = model.geom_conaffinity[g] = 0


def load_model(spec: RobotSpec, options: Mapping[str, Any] | None = None,
               source: str = "<model_options>") -> mujoco.MjModel:
    """The MuJoCo model of ``spec`` as MJX runs it: :data:`MJX_ADJUSTMENTS` and ``options`` applied."""
    model = mujoco.MjModel.from_xml_path(spec.xml_path)
    apply_model_options(model, options or {}, source)
    return model
