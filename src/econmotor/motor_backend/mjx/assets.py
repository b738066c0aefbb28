"""The robots of the mjx couriers: Gymnasium's own MJCF files and v5 env parameters.

The model file and every reward / healthy / reset parameter are read from the installed
Gymnasium v5 env class (its ``__init__`` defaults, overridden by the catalog's ``env_kwargs``),
so the mjx env's observation, action, reward and fall definitions are the ones the ``mujoco``
backend gets from ``gymnasium.make(env_id)``; nothing is copied by hand.

MJX cannot run some MJCF options; :func:`load_model` changes them at load and says so in
:data:`MJX_ADJUSTMENTS`:

- ``humanoid.xml`` uses the PGS constraint solver; MJX implements CG and Newton only, so the
  solver becomes Newton (same iterations and tolerance). A parity test comparing MuJoCo C with
  MJX must build the C side with :func:`load_model` too.
"""

from __future__ import annotations

import inspect
import os
from dataclasses import dataclass, field
from typing import Any

import gymnasium as gym
import mujoco

from econmotor.errors import ConfigError

#: env id -> robot kind (the healthy rule and observation layout of that Gymnasium env).
ROBOTS = {"Hopper-v5": "hopper", "Walker2d-v5": "walker2d", "Ant-v5": "ant", "Humanoid-v5": "humanoid"}

#: what load_model changes for MJX, per robot (documented in the module docstring).
MJX_ADJUSTMENTS = {"humanoid": "opt.solver: PGS -> Newton (MJX has CG and Newton only)"}

#: Gymnasium kwargs the mjx env does not implement (they change rendering or the observation).
_UNSUPPORTED = ("exclude_current_positions_from_observation", "include_cfrc_ext_in_observation",
                "include_cinert_in_observation", "include_cvel_in_observation",
                "include_qfrc_actuator_in_observation", "terminate_when_unhealthy", "main_body")


@dataclass(frozen=True)
class RobotSpec:
    """One Gymnasium v5 env's model file and parameters."""

    env_id: str
    robot: str
    xml_path: str
    params: dict[str, Any] = field(default_factory=dict)
    max_episode_steps: int = 1000

    def __getitem__(self, key: str) -> Any:
        return self.params[key]


def robot_spec(env_id: str, env_kwargs: dict[str, Any] | None = None, source: str = "<catalog>") -> RobotSpec:
    """The parameters of ``gymnasium.make(env_id, **env_kwargs)`` without building it."""
    if env_id not in ROBOTS:
        raise ConfigError(source, "env_id", f"the mjx backend has no model for '{env_id}'", list(ROBOTS))
    kwargs = dict(env_kwargs or {})
    gspec = gym.spec(env_id)
    max_steps = int(kwargs.pop("max_episode_steps", gspec.max_episode_steps or 1000))
    cls = gym.envs.registration.load_env_creator(gspec.entry_point)
    params = {name: p.default for name, p in inspect.signature(cls.__init__).parameters.items()
              if p.default is not inspect.Parameter.empty}
    for name, value in kwargs.items():
        if name not in params or name in _UNSUPPORTED or name == "default_camera_config":
            allowed = [k for k in params if k not in _UNSUPPORTED and k != "default_camera_config"]
            raise ConfigError(source, f"env_kwargs.{name}", "the mjx backend cannot honour this option",
                              ["max_episode_steps", *allowed])
        params[name] = value
    xml = params["xml_file"]
    if not os.path.isabs(xml):
        xml = os.path.join(os.path.dirname(inspect.getfile(cls)), "assets", xml)
    return RobotSpec(env_id, ROBOTS[env_id], xml, params, max_steps)


def load_model(spec: RobotSpec) -> mujoco.MjModel:
    """The MuJoCo model of ``spec`` with the MJX adjustments of :data:`MJX_ADJUSTMENTS` applied."""
    model = mujoco.MjModel.from_xml_path(spec.xml_path)
    if model.opt.solver == mujoco.mjtSolver.mjSOL_PGS:
        model.opt.solver = mujoco.mjtSolver.mjSOL_NEWTON
    return model
