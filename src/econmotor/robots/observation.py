"""The policy's observation, holosoma_inference's convention, written once for NumPy and JAX.

Every function takes ``xp``, the array namespace (``numpy`` on the host, ``jax.numpy`` inside a
jitted, vmapped step) and works on one robot's arrays (1-D) or a batch of robots (``[N, ...]``:
every function reads and writes the last axis). The terms
(holosoma_inference's ``get_current_obs_buffer_dict``):

- ``base_ang_vel``: the root's angular velocity in its own frame (MuJoCo's ``qvel[3:6]``),
- ``projected_gravity``: the world's -z axis in the root frame, from the root quaternion (w, x, y, z),
- ``command_lin_vel`` (vx, vy) and ``command_ang_vel`` (yaw rate),
- ``dof_pos`` minus the default pose, ``dof_vel``, ``actions`` (the last clipped policy output),
- ``sin_phase`` / ``cos_phase`` of the two feet's gait clock (:func:`advance_phase`).

:func:`actor_obs` multiplies each by its scale and concatenates them in the card's (sorted)
order; float32, as the ONNX policies take it. ``tests/integration/test_robot_cards.py`` holds it
to holosoma_inference's own code on the same states.
"""

from __future__ import annotations

import math
from typing import Any

from econmotor.robots.card import RobotCard


def projected_gravity(quat_wxyz: Any, xp: Any) -> Any:
    """Gravity's direction in the body frame: minus the third row of the body-to-world rotation."""
    w, x, y, z = quat_wxyz[..., 0], quat_wxyz[..., 1], quat_wxyz[..., 2], quat_wxyz[..., 3]
    return -xp.stack([2.0 * (x * z - w * y), 2.0 * (y * z + w * x), 1.0 - 2.0 * (x * x + y * y)], axis=-1)


def rotate_inverse(quat_wxyz: Any, v: Any, xp: Any) -> Any:
    """World vectors ``v`` [..., 3] in the body frames ``quat_wxyz`` [..., 4]: ``R(q)^T v``, written
    ``v (2 w^2 - 1) - 2 w (u x v) + 2 u (u . v)`` with ``u = (x, y, z)`` (one robot or a batch; NumPy or JAX)."""
    w, u = quat_wxyz[..., :1], quat_wxyz[..., 1:4]
    return v * (2.0 * w * w - 1.0) - 2.0 * w * xp.cross(u, v) + 2.0 * u * xp.sum(u * v, axis=-1, keepdims=True)


def initial_phase(xp: Any) -> Any:
    """The gait clock at an episode's start: (0, pi) for the left and right foot."""
    return xp.asarray([0.0, math.pi])


def advance_phase(phase: Any, standing: Any, lin_vel_cmd: Any, ang_vel_cmd: Any, card: RobotCard,
                  xp: Any) -> tuple[Any, Any]:
    """One control step of the gait clock: ``(phase', standing')``.

    ``phase' = fmod(phase + phase_dt + pi, 2 pi) - pi``; while the command is "stand" (``|v| <
    stand_eps`` and ``|yaw rate| < stand_eps``) both feet sit at pi; the first step after a stand
    restarts the clock at (0, pi) (holosoma_inference's ``update_phase_time``).
    """
    eps = card.observation.stand_eps
    moved = xp.fmod(phase + card.phase_dt + math.pi, 2.0 * math.pi) - math.pi
    stand = xp.logical_and(xp.sqrt(xp.sum(xp.square(lin_vel_cmd), axis=-1)) < eps, xp.abs(ang_vel_cmd) < eps)
    restarted = xp.where(xp.expand_dims(xp.asarray(standing), -1), initial_phase(xp), moved)
    return xp.where(xp.expand_dims(stand, -1), xp.full_like(moved, math.pi), restarted), stand


def observation_terms(card: RobotCard, *, quat_wxyz: Any, ang_vel_body: Any, q: Any, qd: Any, lin_vel_cmd: Any,
                      ang_vel_cmd: Any, last_action: Any, phase: Any, xp: Any) -> dict[str, Any]:
    """The unscaled terms of one state (``q``, ``qd``, ``last_action`` in the card's joint order)."""
    return {
        "actions": last_action,
        "base_ang_vel": ang_vel_body,
        "command_ang_vel": xp.expand_dims(xp.asarray(ang_vel_cmd), -1),
        "command_lin_vel": lin_vel_cmd,
        "cos_phase": xp.cos(phase),
        "dof_pos": q - xp.asarray(card.default_dof_angles),
        "dof_vel": qd,
        "projected_gravity": projected_gravity(quat_wxyz, xp),
        "sin_phase": xp.sin(phase),
    }


def actor_obs(card: RobotCard, terms: dict[str, Any], xp: Any) -> Any:
    """One ``actor_obs`` row (float32): each of the card's terms times its scale, in the card's order.

    History longer than one frame needs a buffer the caller keeps; the shipped conventions use one.
    """
    conv = card.observation
    if conv.history_length != 1:
        raise NotImplementedError(f"robot card {card.name}: observation history {conv.history_length} "
                                  "(one frame is built here)")
    # scaled in the terms' own precision, then float32 (as holosoma_inference and the evaluator do)
    parts = [xp.asarray(xp.asarray(terms[t]) * conv.scales[t], dtype=xp.float32) for t in conv.terms]
    return xp.concatenate(parts, axis=-1)


def build_observation(card: RobotCard, xp: Any, **state: Any) -> Any:
    """:func:`actor_obs` of :func:`observation_terms` (``state``: that function's keyword arguments)."""
    return actor_obs(card, observation_terms(card, xp=xp, **state), xp)
