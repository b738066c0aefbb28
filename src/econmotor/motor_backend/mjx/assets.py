"""The robots of the mjx couriers: Gymnasium's own MJCF files, loaded for MJX.

The robot records (model file, Gymnasium v5 parameters, healthy rule, observation, reward and
reset facts) are the couriers' (``couriers/robots.py``: :func:`robot_spec` applies a catalog
entry's ``env_kwargs``), so the mjx env's observation, action, reward and fall definitions are
the ones the ``mujoco`` backend gets from ``gymnasium.make(env_id)``, without importing
gymnasium here.

MJX cannot run some MJCF options; :func:`load_model` changes them at load and says so in
:data:`MJX_ADJUSTMENTS`:

- ``humanoid.xml`` uses the PGS constraint solver; MJX implements CG and Newton only, so the
  solver becomes Newton (same iterations and tolerance). A parity test comparing MuJoCo C with
  MJX must build the C side with :func:`load_model` too.
"""

from __future__ import annotations

import mujoco

from econmotor.motor_backend.couriers.robots import ROBOTS, RobotSpec, robot_spec

__all__ = ["MJX_ADJUSTMENTS", "ROBOTS", "RobotSpec", "load_model", "robot_spec"]

#: what load_model changes for MJX (documented in the module docstring).
MJX_ADJUSTMENTS = {"opt.solver": "PGS -> Newton (MJX has CG and Newton only; humanoid.xml uses PGS)"}


def load_model(spec: RobotSpec) -> mujoco.MjModel:
    """The MuJoCo model of ``spec`` with the MJX adjustments of :data:`MJX_ADJUSTMENTS` applied."""
    model = mujoco.MjModel.from_xml_path(spec.xml_path)
    if model.opt.solver == mujoco.mjtSolver.mjSOL_PGS:
        model.opt.solver = mujoco.mjtSolver.mjSOL_NEWTON
    return model
