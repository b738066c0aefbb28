"""The delivery course as pure functions of an array namespace ``xp`` (NumPy, or JAX in a jitted step).

One implementation for every caller: the batched MuJoCo walker env (:mod:`.env`, NumPy
arrays over its robots) and the ``mjx`` humanoid couriers (JAX, inside their compiled step) run
the same lines on the settings :class:`CourseSettings`:

- legs of ``leg_m`` along +x; on a leg the command is the course speed (capped at the policy's
  command range) and a yaw rate ``clip(yaw_gain * heading error)`` towards the point
  ``lookahead_m`` ahead on the centre line ``y = 0``;
- reaching a leg's end starts a dwell of ``dwell_s`` (the pick-and-place) commanding (0, 0);
  the next leg starts when it is over;
- the course is finished once ``legs`` legs (0: never) are walked and the last dwell stood.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, NamedTuple

__all__ = ["CourseSettings", "CourseState", "course_command", "course_finished", "course_start", "heading_yaw"]


@dataclass(frozen=True)
class CourseSettings:
    """The delivery course: legs of ``leg_m`` along +x, ``dwell_s`` standing at each leg end.

    ``speed_m_per_s``: the commanded walking speed; ``legs``: the episode ends when the last leg's
    dwell does (0: at the time limit only), so every unit an episode counts carries its dwell, as
    the human's does; ``lookahead_m`` / ``yaw_gain``: the heading controller (yaw rate in rad/s per
    rad of heading error towards the point ``lookahead_m`` ahead on the centre line).
    """

    leg_m: float
    dwell_s: float
    speed_m_per_s: float
    legs: int = 0
    lookahead_m: float = 1.0
    yaw_gain: float = 2.0


class CourseState(NamedTuple):
    """Where a robot is on the course: its leg, the dwell left (s) and the legs walked (floats)."""

    leg: Any
    dwell_left_s: Any
    legs_done: Any


def course_start(xp: Any, shape: tuple[int, ...] = ()) -> CourseState:
    """The first leg, no dwell, nothing walked (``shape``: one state per robot of a batch)."""
    return CourseState(xp.zeros(shape), xp.zeros(shape), xp.zeros(shape))


def heading_yaw(quat_wxyz: Any, xp: Any) -> Any:
    """The yaw (rad) of the base quaternion (w, x, y, z) on the last axis."""
    w, x, y, z = quat_wxyz[..., 0], quat_wxyz[..., 1], quat_wxyz[..., 2], quat_wxyz[..., 3]
    return xp.arctan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def course_finished(state: CourseState, course: CourseSettings, xp: Any) -> Any:
    """Every leg walked and its dwell stood (never, with ``course.legs == 0``)."""
    return xp.logical_and(xp.logical_and(course.legs > 0, state.legs_done >= course.legs),
                          xp.logical_not(state.dwell_left_s > 0.0))


def course_command(state: CourseState, x: Any, y: Any, yaw: Any, course: CourseSettings, dt_s: float,
                   vx_max: float, yaw_range: tuple[float, float], xp: Any) -> tuple[CourseState, Any, Any]:
    """One control step at base position ``(x, y)`` and heading ``yaw``: ``(state', vx m/s, yaw rate rad/s)``."""
    dwelling = state.dwell_left_s > 0.0
    # dwelling: count the dwell down; the next leg starts once it is over
    dwell_after = state.dwell_left_s - dt_s
    leg_after_dwell = state.leg + xp.where(dwell_after > 0.0, 0.0, 1.0)
    # walking: the leg's end starts a dwell (or, without one, the next leg at once)
    reached = x >= (state.leg + 1.0) * course.leg_m
    start_dwell = xp.logical_and(reached, course.dwell_s > 0.0)
    leg_walking = state.leg + xp.where(xp.logical_and(reached, xp.logical_not(start_dwell)), 1.0, 0.0)
    error = xp.arctan2(-y, course.lookahead_m) - yaw
    error = xp.arctan2(xp.sin(error), xp.cos(error))
    yaw_rate = xp.clip(course.yaw_gain * error, yaw_range[0], yaw_range[1])
    walk = xp.logical_and(xp.logical_not(dwelling), xp.logical_not(start_dwell))
    new = CourseState(
        leg=xp.where(dwelling, leg_after_dwell, leg_walking),
        dwell_left_s=xp.where(dwelling, dwell_after, xp.where(start_dwell, course.dwell_s, 0.0)),
        legs_done=state.legs_done + xp.where(xp.logical_and(xp.logical_not(dwelling), reached), 1.0, 0.0))
    vx = xp.where(walk, min(course.speed_m_per_s, vx_max), 0.0)
    return new, vx, xp.where(walk, yaw_rate, 0.0)
