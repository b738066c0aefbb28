"""What the couriers' metering reads from a MuJoCo model and state, for any robot.

- :func:`actuated_dof_span`: the dofs power is summed over,
- :func:`has_free_root`: whether the root joint is free-floating (Ant, Humanoid) or planar,
- :func:`root_tilt_rad`: the torso's angle from upright, from ``qpos`` (:func:`quat_tilt_rad`: from a quaternion).

``model`` is a ``mujoco.MjModel`` (the mjx backend's too, before ``mjx.put_model``).
"""

from __future__ import annotations

from typing import Any

import mujoco
import numpy as np


def actuated_dof_span(model: Any) -> tuple[int, int]:
    """``(lo, hi)``: the smallest dof range holding every joint-driven actuator's dof.

    Power is summed over ``qfrc_actuator[lo:hi] * qvel[lo:hi]``; unactuated dofs inside the
    range read ``qfrc_actuator = 0`` and add nothing. Any non-joint transmission (tendon,
    site, ...) can push force onto any dof, so then the range is all ``nv`` dofs.
    """
    joint_types = (int(mujoco.mjtTrn.mjTRN_JOINT), int(mujoco.mjtTrn.mjTRN_JOINTINPARENT))
    gravcomp = getattr(model, "jnt_actgravcomp", None)  # actuator gravity compensation also lands there
    if (model.nu == 0 or any(int(t) not in joint_types for t in model.actuator_trntype)
            or (gravcomp is not None and bool(np.any(gravcomp)))):
        return 0, int(model.nv)
    joints = [int(j) for j in model.actuator_trnid[:, 0]]
    ndof = {int(mujoco.mjtJoint.mjJNT_FREE): 6, int(mujoco.mjtJoint.mjJNT_BALL): 3}
    lo = min(int(model.jnt_dofadr[j]) for j in joints)
    hi = max(int(model.jnt_dofadr[j]) + ndof.get(int(model.jnt_type[j]), 1) for j in joints)
    return lo, hi


def has_free_root(model: Any) -> bool:
    """Whether joint 0 is a free joint (``qpos[3:7]`` the root quaternion) rather than planar slides and a hinge."""
    return int(model.jnt_type[0]) == int(mujoco.mjtJoint.mjJNT_FREE)


def root_tilt_rad(qpos: Any, free_root: bool, xp: Any) -> Any:
    """The torso's angle from upright, rad.

    Planar robots: ``|qpos[2]|`` (the root hinge). Free roots: from the quaternion
    ``(w, x, y, z) = qpos[3:7]``, ``acos(1 - 2 (x^2 + y^2))`` (the angle between the body's z
    axis and the world's), its argument clipped to [-1, 1] against rounding.
    """
    if free_root:
        return quat_tilt_rad(qpos[4], qpos[5], xp)
    return xp.abs(qpos[2])


def has_fallen(card: Any, qpos: Any, qvel: Any, xp: Any, runaway_speed_m_per_s: float | None = None,
               tilt_rad: Any = None) -> Any:
    """A card robot's fall rule on its free-root state (last axis; any leading batch axes): tilt past
    ``card.fall_tilt_rad``, the root below ``card.min_base_z_m``, or the runaway rule: a non-finite
    state or the root's speed ``|qvel[0:3]|`` past ``runaway_speed_m_per_s`` (default: the card's).
    ``tilt_rad``: the tilt where the caller has it (else from ``qpos``'s quaternion)."""
    limit = card.runaway_speed_m_per_s if runaway_speed_m_per_s is None else runaway_speed_m_per_s
    tilt = quat_tilt_rad(qpos[..., 4], qpos[..., 5], xp) if tilt_rad is None else tilt_rad
    finite = xp.logical_and(xp.all(xp.isfinite(qpos), axis=-1), xp.all(xp.isfinite(qvel), axis=-1))
    speed = xp.sqrt(xp.sum(xp.square(qvel[..., 0:3]), axis=-1))
    return (tilt > card.fall_tilt_rad) | (qpos[..., 2] < card.min_base_z_m) | ~finite | (speed > limit)


def quat_tilt_rad(qx: Any, qy: Any, xp: Any) -> Any:
    """The angle between a body's z axis and the world's, rad, from its unit quaternion's ``x`` and ``y``
    (any component order): ``acos(1 - 2 (x^2 + y^2))``, the argument clipped to [-1, 1] against rounding."""
    return xp.arccos(xp.clip(1.0 - 2.0 * (qx * qx + qy * qy), -1.0, 1.0))
