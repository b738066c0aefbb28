"""Locomotion reward terms of the humanoid couriers: small named pure functions ``f(r, xp, **params)``.

Holosoma's locomotion terms (``holosoma/managers/reward/terms/locomotion.py``; its G1 and T1
presets in ``holosoma/config_values/loco/{g1,t1}/reward.py`` give the weights the catalog copies,
``tasks/mjx.yaml``), which in turn follow MuJoCo Playground's G1 joystick: each reads a
:class:`LocomotionReading` of one env after a control step and returns a scalar; a reading whose
arrays carry a leading robot axis (the mujoco walker trainer's batch) gives one value per robot
(``alive`` gives 1, which broadcasts). The step's locomotion reward is
``sum_k weight_k * term_k * control_dt_s`` (Holosoma's reward manager scales by the step),
:func:`locomotion_reward`.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from typing import Any, NamedTuple


class LocomotionReading(NamedTuple):
    """What the terms read from one env after a control step (body frame: the root's)."""

    command: Any  # (vx m/s, vy m/s, yaw rate rad/s) the course commanded for this step
    lin_vel_body: Any  # the root's linear velocity in its own frame, m/s (3)
    ang_vel_body: Any  # the root's angular velocity in its own frame, rad/s (3)
    gravity_body: Any  # gravity's direction in the root frame (3)
    action: Any  # this step's (clipped) action
    last_action: Any  # the previous step's
    q: Any  # joint positions, the card's order
    default_q: Any  # the card's default pose
    phase: Any  # the gait clock of the two feet at this step, rad (2)
    foot_z: Any  # heights of the two foot contact points above the floor, m (2)
    feet_xy: Any  # the two feet's xy positions, m (2, 2)
    feet_gravity_xy: Any  # gravity's xy in each foot's frame (2, 2)
    base_yaw: Any  # the root's heading, rad


def tracking_lin_vel(r: LocomotionReading, xp: Any, tracking_sigma: float = 0.25) -> Any:
    """``exp(-|cmd_xy - v_xy|^2 / sigma)``: the commanded planar velocity, tracked."""
    return xp.exp(-xp.sum(xp.square(r.command[..., :2] - r.lin_vel_body[..., :2]), axis=-1) / tracking_sigma)


def tracking_ang_vel(r: LocomotionReading, xp: Any, tracking_sigma: float = 0.25) -> Any:
    """``exp(-(cmd_yaw - w_z)^2 / sigma)``: the commanded yaw rate, tracked."""
    return xp.exp(-xp.square(r.command[..., 2] - r.ang_vel_body[..., 2]) / tracking_sigma)


def penalty_ang_vel_xy(r: LocomotionReading, xp: Any) -> Any:
    """``w_x^2 + w_y^2``: roll and pitch rates."""
    return xp.sum(xp.square(r.ang_vel_body[..., :2]), axis=-1)


def penalty_orientation(r: LocomotionReading, xp: Any) -> Any:
    """``g_x^2 + g_y^2`` of gravity in the body frame: a base that is not level."""
    return xp.sum(xp.square(r.gravity_body[..., :2]), axis=-1)


def penalty_action_rate(r: LocomotionReading, xp: Any) -> Any:
    """``|a - a_prev|^2``: jerky actions."""
    return xp.sum(xp.square(r.action - r.last_action), axis=-1)


def expected_foot_height(phase: Any, swing_height: float, xp: Any) -> Any:
    """The foot height the gait clock asks for: a cubic Bezier up to ``swing_height`` and back (Holosoma)."""
    x = (phase + math.pi) / (2.0 * math.pi)

    def bezier(y0: Any, y1: Any, s: Any) -> Any:
        return y0 + (y1 - y0) * (s ** 3 + 3.0 * (s ** 2 * (1.0 - s)))

    return xp.where(x <= 0.5, bezier(0.0, swing_height, 2.0 * x), bezier(swing_height, 0.0, 2.0 * x - 1.0))


def feet_phase(r: LocomotionReading, xp: Any, swing_height: float = 0.08, tracking_sigma: float = 0.25) -> Any:
    """``exp(-sum_feet (z - z_expected(phase))^2 / sigma)``: feet that swing as the clock says."""
    error = xp.sum(xp.square(r.foot_z - expected_foot_height(r.phase, swing_height, xp)), axis=-1)
    return xp.exp(-error / tracking_sigma)


def pose(r: LocomotionReading, xp: Any, pose_weights: Any = None) -> Any:
    """``sum_j w_j (q_j - default_j)^2``: a pose away from the default one."""
    weights = xp.asarray(pose_weights) if pose_weights is not None else 1.0
    return xp.sum(weights * xp.square(r.q - r.default_q), axis=-1)


def penalty_close_feet_xy(r: LocomotionReading, xp: Any, close_feet_threshold: float = 0.05) -> Any:
    """1 when the feet are closer than the threshold across the base's heading (a step onto the other foot)."""
    d = r.feet_xy[..., 0, :] - r.feet_xy[..., 1, :]
    across = xp.abs(xp.cos(r.base_yaw) * d[..., 1] - xp.sin(r.base_yaw) * d[..., 0])
    return xp.where(across < close_feet_threshold, 1.0, 0.0)


def penalty_feet_ori(r: LocomotionReading, xp: Any) -> Any:
    """``sum_feet |g_xy|`` in each foot's frame: feet that are not flat."""
    return xp.sum(xp.sqrt(xp.sum(xp.square(r.feet_gravity_xy), axis=-1)), axis=-1)


def alive(r: LocomotionReading, xp: Any) -> Any:
    """1 per step the robot is up."""
    return xp.asarray(1.0)


#: the terms by Holosoma's name
TERMS: dict[str, Callable[..., Any]] = {f.__name__: f for f in (
    tracking_lin_vel, tracking_ang_vel, penalty_ang_vel_xy, penalty_orientation, penalty_action_rate, feet_phase,
    pose, penalty_close_feet_xy, penalty_feet_ori, alive)}


def locomotion_reward(r: LocomotionReading, weights: Mapping[str, float], params: Mapping[str, Mapping[str, Any]],
                      dt_s: float, xp: Any) -> tuple[Any, dict[str, Any]]:
    """``(sum_k weight_k * term_k * dt_s, {k: term_k})`` over the weighted terms."""
    raw = {k: TERMS[k](r, xp, **params.get(k, {})) for k in weights}
    total = sum(float(weights[k]) * raw[k] for k in weights) * dt_s
    return total, raw
