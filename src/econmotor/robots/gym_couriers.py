"""The courier robots: one record per Gymnasium v5 MuJoCo robot, with the rules both couriers share.

A :class:`CourierRobot` holds what the ``mjx`` backend rebuilds of a Gymnasium env (and the
``mujoco`` backend gets from ``gymnasium.make``): the model file, the v5 constructor defaults,
the healthy (fall) rule, the observation's parts, how the task reward reads forward motion and
contact forces, and the reset noise. Code reads these fields; it never branches on a robot's
name. The defaults are Gymnasium 1.x's, copied here so that this package imports no
gymnasium; ``tests/unit/couriers/test_courier_robots.py`` holds them to the installed
env classes and :func:`is_healthy` to the envs' own ``is_healthy``.
"""

from __future__ import annotations

import importlib.util
import math
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from econmotor.errors import ConfigError

#: observation parts (in order) a robot's record may list; each is read from MuJoCo's data.
OBS_PARTS = ("qpos", "qvel", "qvel_clipped", "cinert", "cvel", "qfrc_actuator", "cfrc_ext", "cfrc_ext_clipped")
#: how the task reward reads forward motion: the root's x, the main body's x, the mass centre's x.
FORWARD_X = ("root_x", "main_body_x", "mass_centre_x")
#: the task reward's contact cost: per-force clip then sum of squares (Ant), or clip of the weighted sum (Humanoid).
CONTACT_COSTS = (None, "clipped_forces", "clipped_total")

#: Gymnasium kwargs the couriers do not implement (they change rendering or the observation).
UNSUPPORTED_KWARGS = ("exclude_current_positions_from_observation", "include_cfrc_ext_in_observation",
                      "include_cinert_in_observation", "include_cvel_in_observation",
                      "include_qfrc_actuator_in_observation", "terminate_when_unhealthy", "main_body",
                      "default_camera_config")


@dataclass(frozen=True)
class HealthyRule:
    """Gymnasium v5's ``is_healthy`` of one robot (the ranges come from the env's parameters)."""

    z_index: int
    z_range: tuple[float, float]
    inclusive: bool = False  # Ant-v5: lo <= z <= hi; the others: lo < z < hi
    angle_range: tuple[float, float] | None = None  # planar robots: qpos[2]
    state_range: tuple[float, float] | None = None  # Hopper-v5: every entry of state_vector()[2:]
    finite: bool = False  # Ant-v5: the whole state vector is finite


def is_healthy(rule: HealthyRule, qpos: Any, qvel: Any, xp: Any) -> Any:
    """``rule`` applied to one state (1-D ``qpos``/``qvel``, NumPy or JAX under vmap): a bool (array)."""
    lo, hi = rule.z_range
    z = qpos[rule.z_index]
    ok = xp.logical_and(lo <= z, z <= hi) if rule.inclusive else xp.logical_and(lo < z, z < hi)
    if rule.angle_range is not None:
        a_lo, a_hi = rule.angle_range
        ok = xp.logical_and(ok, xp.logical_and(a_lo < qpos[2], qpos[2] < a_hi))
    if rule.state_range is not None:
        s_lo, s_hi = rule.state_range
        state = xp.concatenate([qpos[2:], qvel])
        ok = xp.logical_and(ok, xp.all(xp.logical_and(s_lo < state, state < s_hi)))
    if rule.finite:
        ok = xp.logical_and(ok, xp.logical_and(xp.all(xp.isfinite(qpos)), xp.all(xp.isfinite(qvel))))
    return ok


@dataclass(frozen=True)
class CourierRobot:
    """One Gymnasium v5 robot as the couriers read it (module docstring).

    Fields: ``name``, ``env_id``; ``xml_file`` (in Gymnasium's ``envs/mujoco/assets``);
    ``defaults``: the v5 constructor's defaults (those a catalog's ``env_kwargs`` may override);
    ``max_episode_steps``: the registered time limit. Health: ``z_index`` (qpos entry of the
    height), ``z_inclusive``, and which of ``healthy_angle_range`` (``qpos[2]``),
    ``healthy_state_range`` (``state_vector()[2:]``) and finiteness the rule checks. Observation:
    ``qpos[obs_qpos_start:]`` then ``obs_parts`` (:data:`OBS_PARTS`; ``*_clipped``: qvel to
    ``[-10, 10]``, contact forces to ``contact_force_range``; body rows from body 1, actuator
    forces past the free root's 6 dofs). Reward: ``forward_x`` (:data:`FORWARD_X`),
    ``contact_cost`` (:data:`CONTACT_COSTS`). Reset: ``reset_qvel_noise`` ``"uniform"`` or
    ``"normal"`` (scaled by ``reset_noise_scale``; qpos noise is uniform for all).
    """

    name: str
    env_id: str
    xml_file: str
    defaults: Mapping[str, Any]
    z_index: int
    z_inclusive: bool = False
    checks_angle: bool = False
    checks_state: bool = False
    checks_finite: bool = False
    obs_qpos_start: int = 1
    obs_parts: tuple[str, ...] = ("qpos", "qvel_clipped")
    forward_x: str = "root_x"
    contact_cost: str | None = None
    reset_qvel_noise: str = "uniform"
    max_episode_steps: int = 1000

    @property
    def reads_contact_forces(self) -> bool:
        """Whether the observation or the reward reads ``cfrc_ext`` (MuJoCo computes it on request)."""
        return self.contact_cost is not None or any(p.startswith("cfrc_ext") for p in self.obs_parts)

    @property
    def obs_reads_body_kinematics(self) -> bool:
        """Whether the observation reads ``cinert`` / ``cvel`` (a reset state needs its kinematics then)."""
        return "cinert" in self.obs_parts or "cvel" in self.obs_parts

    def healthy_rule(self, params: Mapping[str, Any]) -> HealthyRule:
        """The :class:`HealthyRule` under the env parameters ``params`` (:func:`robot_params`)."""
        return HealthyRule(
            self.z_index, tuple(float(v) for v in params["healthy_z_range"]), self.z_inclusive,
            tuple(params["healthy_angle_range"]) if self.checks_angle else None,
            tuple(params["healthy_state_range"]) if self.checks_state else None,
            self.checks_finite,
        )


HOPPER = CourierRobot(
    "hopper", "Hopper-v5", "hopper.xml",
    {"xml_file": "hopper.xml", "frame_skip": 4, "forward_reward_weight": 1.0, "ctrl_cost_weight": 1e-3,
     "healthy_reward": 1.0, "terminate_when_unhealthy": True, "healthy_state_range": (-100.0, 100.0),
     "healthy_z_range": (0.7, math.inf), "healthy_angle_range": (-0.2, 0.2), "reset_noise_scale": 5e-3,
     "exclude_current_positions_from_observation": True},
    z_index=1, checks_angle=True, checks_state=True)
WALKER2D = CourierRobot(
    "walker2d", "Walker2d-v5", "walker2d_v5.xml",
    {"xml_file": "walker2d_v5.xml", "frame_skip": 4, "forward_reward_weight": 1.0, "ctrl_cost_weight": 1e-3,
     "healthy_reward": 1.0, "terminate_when_unhealthy": True, "healthy_z_range": (0.8, 2.0),
     "healthy_angle_range": (-1.0, 1.0), "reset_noise_scale": 5e-3,
     "exclude_current_positions_from_observation": True},
    z_index=1, checks_angle=True)
ANT = CourierRobot(
    "ant", "Ant-v5", "ant.xml",
    {"xml_file": "ant.xml", "frame_skip": 5, "forward_reward_weight": 1, "ctrl_cost_weight": 0.5,
     "contact_cost_weight": 5e-4, "healthy_reward": 1.0, "main_body": 1, "terminate_when_unhealthy": True,
     "healthy_z_range": (0.2, 1.0), "contact_force_range": (-1.0, 1.0), "reset_noise_scale": 0.1,
     "exclude_current_positions_from_observation": True, "include_cfrc_ext_in_observation": True},
    z_index=2, z_inclusive=True, checks_finite=True, obs_qpos_start=2,
    obs_parts=("qpos", "qvel", "cfrc_ext_clipped"), forward_x="main_body_x", contact_cost="clipped_forces",
    reset_qvel_noise="normal")
HUMANOID = CourierRobot(
    "humanoid", "Humanoid-v5", "humanoid.xml",
    {"xml_file": "humanoid.xml", "frame_skip": 5, "forward_reward_weight": 1.25, "ctrl_cost_weight": 0.1,
     "contact_cost_weight": 5e-7, "contact_cost_range": (-math.inf, 10.0), "healthy_reward": 5.0,
     "terminate_when_unhealthy": True, "healthy_z_range": (1.0, 2.0), "reset_noise_scale": 1e-2,
     "exclude_current_positions_from_observation": True, "include_cinert_in_observation": True,
     "include_cvel_in_observation": True, "include_qfrc_actuator_in_observation": True,
     "include_cfrc_ext_in_observation": True},
    z_index=2, obs_qpos_start=2, obs_parts=("qpos", "qvel", "cinert", "cvel", "qfrc_actuator", "cfrc_ext"),
    forward_x="mass_centre_x", contact_cost="clipped_total")

#: env id -> robot record.
ROBOTS: dict[str, CourierRobot] = {r.env_id: r for r in (HOPPER, WALKER2D, ANT, HUMANOID)}


def robot_name(env_id: str) -> str:
    """The robot behind a Gymnasium MuJoCo env id, named apart from any backend: its record's ``name``
    (``Hopper-v5`` -> ``hopper``), else the id without its version, lower case (``HalfCheetah-v5`` ->
    ``halfcheetah``)."""
    robot = ROBOTS.get(env_id)
    return robot.name if robot is not None else env_id.split("-v")[0].lower()


@dataclass(frozen=True)
class RobotSpec:
    """A robot under one catalog entry's ``env_kwargs``: its record, parameters, model file and time limit."""

    robot: CourierRobot
    xml_path: str
    params: dict[str, Any] = field(default_factory=dict)
    max_episode_steps: int = 1000

    def __getitem__(self, key: str) -> Any:
        return self.params[key]


def gymnasium_assets_dir() -> str:
    """Gymnasium's ``envs/mujoco/assets`` folder, found without importing gymnasium."""
    spec = importlib.util.find_spec("gymnasium")
    if spec is None or not spec.submodule_search_locations:
        raise ConfigError("<environment>", "gymnasium", "is not installed: the courier model files ship with it")
    return os.path.join(next(iter(spec.submodule_search_locations)), "envs", "mujoco", "assets")


def robot_spec(env_id: str, env_kwargs: Mapping[str, Any] | None = None, source: str = "<catalog>") -> RobotSpec:
    """The parameters of ``gymnasium.make(env_id, **env_kwargs)`` without building (or importing) it."""
    if env_id not in ROBOTS:
        raise ConfigError(source, "env_id", f"the couriers have no model for '{env_id}'", list(ROBOTS))
    robot = ROBOTS[env_id]
    kwargs = dict(env_kwargs or {})
    max_steps = int(kwargs.pop("max_episode_steps", robot.max_episode_steps))
    params = dict(robot.defaults)
    for name, value in kwargs.items():
        if name not in params or name in UNSUPPORTED_KWARGS:
            allowed = [k for k in params if k not in UNSUPPORTED_KWARGS]
            raise ConfigError(source, f"env_kwargs.{name}", "the mjx backend cannot honour this option",
                              ["max_episode_steps", *allowed])
        params[name] = value
    xml = str(params["xml_file"])
    if not os.path.isabs(xml):
        xml = os.path.join(gymnasium_assets_dir(), xml)
    return RobotSpec(robot, xml, params, max_steps)
