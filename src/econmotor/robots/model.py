"""A robot card's MuJoCo model: its maker's MJCF, a floor, its maker's collision filter.

:func:`model_spec` builds, from the card alone (every interpreter, every backend the same way):

1. the MJCF read from the installed package (:func:`mjcf_path`, found without importing it);
   visual-only mesh geoms (no collisions, no mass) and their meshes are dropped unless
   ``visual=True``: they change no dynamics, and MJX and the evaluator need no mesh files;
2. the physics step ``card.physics_dt_s``;
3. a floor plane named ``floor`` when the MJCF has none (the G1's foot contact pairs name it);
4. the collision filter of Holosoma's MuJoCo simulator (``scene_manager._configure_robot_collisions``)
   when ``card.self_collisions`` is False: the floor is class 2 (``contype 2, conaffinity 1``),
   every colliding robot geom keeps ``contype 1`` and gets ``conaffinity 2``, so robot geoms touch
   the floor and never each other (Holosoma's T1 MJCF loads in MJX only so: MJX has no
   cylinder-cylinder collider);
5. ``contacts="feet"`` (MJX, as MuJoCo Playground runs these robots): only ``card.foot_geoms``
   collide, with the floor; explicit contact pairs that name another geom are dropped.
"""

from __future__ import annotations

import importlib.util
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from econmotor.errors import ConfigError
from econmotor.robots.card import RobotCard

CONTACTS = ("robot", "feet")
FLOOR = "floor"
#: Holosoma's collision classes (robot geoms: contype 1; the environment: contype 2, conaffinity 1)
_ROBOT_CLASS, _ENV_CLASS = 1, 2


def mjcf_path(card: RobotCard) -> Path:
    """The card's MJCF file in its installed package; a ConfigError says how to install it."""
    spec = importlib.util.find_spec(card.mjcf_package)
    roots = list(spec.submodule_search_locations or ()) if spec is not None else []
    for root in roots:
        path = Path(root) / card.mjcf_file
        if path.is_file():
            return path
    raise ConfigError(f"<robot card {card.name}>", "mjcf_file",
                      f"{card.mjcf_package}/{card.mjcf_file} is not installed in this interpreter; "
                      f"install it with: {card.mjcf_install}")


def _visual_only(geom: Any) -> bool:
    return geom.type == mujoco.mjtGeom.mjGEOM_MESH and geom.contype == 0 and geom.conaffinity == 0


def model_spec(card: RobotCard, *, contacts: str = "robot", visual: bool = False) -> mujoco.MjSpec:
    """The card's model as an editable spec (steps in the module docstring)."""
    if contacts not in CONTACTS:
        raise ValueError(f"contacts must be one of {CONTACTS}, not {contacts!r}")
    spec = mujoco.MjSpec.from_file(str(mjcf_path(card)))
    if not visual:
        dropped = [g for g in spec.geoms if _visual_only(g)]
        for geom in dropped:
            spec.delete(geom)
        used = {g.meshname for g in spec.geoms if g.type == mujoco.mjtGeom.mjGEOM_MESH}
        for mesh in [m for m in spec.meshes if m.name not in used]:
            spec.delete(mesh)
    spec.option.timestep = card.physics_dt_s
    floor = next((g for g in spec.geoms if g.name == FLOOR), None)
    if floor is None:
        floor = spec.worldbody.add_geom(name=FLOOR, type=mujoco.mjtGeom.mjGEOM_PLANE, size=[0.0, 0.0, 0.05])
    robot_geoms = [g for body in spec.bodies if body.name and body.name != "world" for g in body.geoms]
    if not card.self_collisions:
        floor.contype, floor.conaffinity = _ENV_CLASS, _ROBOT_CLASS
        for geom in robot_geoms:
            if geom.contype == 1 and geom.conaffinity == 1:
                geom.conaffinity = _ENV_CLASS
    if contacts == "feet":
        names = {g.name for g in robot_geoms}
        missing = [g for g in card.foot_geoms if g not in names]
        if missing:
            raise ConfigError(f"<robot card {card.name}>", "foot_geoms",
                              f"{missing} are not geoms of {mjcf_path(card)}")
        feet = set(card.foot_geoms)
        for geom in robot_geoms:
            if geom.name not in feet:
                geom.contype = geom.conaffinity = 0
        for pair in [p for p in spec.pairs if not {p.geomname1, p.geomname2} <= feet | {FLOOR}]:
            spec.delete(pair)
    return spec


def load_model(card: RobotCard, *, contacts: str = "robot", visual: bool = False) -> mujoco.MjModel:
    """The compiled :func:`model_spec`."""
    return model_spec(card, contacts=contacts, visual=visual).compile()


def joint_indices(model: mujoco.MjModel, card: RobotCard) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(qpos addresses, dof addresses, actuator ids)`` of ``card.dof_names``, in the card's order.

    Every name must be a hinge joint driven by one actuator; else a ConfigError naming the
    missing joints and the model's.
    """
    hinges = {model.joint(j).name: j for j in range(model.njnt) if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE}
    act = {model.joint(int(model.actuator_trnid[a, 0])).name: a for a in range(model.nu)
           if model.actuator_trntype[a] == mujoco.mjtTrn.mjTRN_JOINT}
    for kind, names in (("hinge joints", hinges), ("actuated joints", act)):
        missing = [n for n in card.dof_names if n not in names]
        if missing:
            raise ConfigError(f"<robot card {card.name}>", "dof_names",
                              f"{missing} are not {kind} of {card.mjcf_file}", sorted(names))
    jids = [hinges[n] for n in card.dof_names]
    return (np.asarray(model.jnt_qposadr[jids]), np.asarray(model.jnt_dofadr[jids]),
            np.asarray([act[n] for n in card.dof_names]))
