"""The delivery course (locomotion/course.py): hand-worked commands, the same in NumPy, in jitted JAX and over a batch.

The course is one set of pure functions, run in NumPy by the batched MuJoCo walker env (a batch of
robots at once) and in JAX inside the ``mjx`` humanoid couriers' compiled step. Held here:

- hand-worked commands on a course whose times are exact in binary (speed capped at the policy's
  range, the yaw rate towards the look-ahead point clipped to it, the heading error wrapped to
  (-pi, pi], the dwell's steps standing, the next leg after it, the finish after the last dwell);
- a scripted trajectory (walking along x with a lateral drift and a heading error, standing at each
  leg end) gives the same commands, dwell and finish in NumPy, in jitted JAX, and for a batch of
  robots in one call as for each robot alone;
- ``heading_yaw`` is the yaw of a rotation built from known yaw, pitch and roll, alike per robot and
  over a batch.
"""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from econmotor.locomotion.course import (
    CourseSettings,
    CourseState,
    course_command,
    course_finished,
    course_start,
    heading_yaw,
)

COURSE = CourseSettings(leg_m=1.0, dwell_s=0.5, speed_m_per_s=0.8, legs=2)
DT = 0.02
VX_MAX, YAW_RANGE = 0.7, (-0.5, 0.5)


def _step(state: CourseState, x: float, y: float, yaw: float, course: CourseSettings = COURSE,
          dt: float = DT) -> tuple[CourseState, float, float]:
    state, vx, w = course_command(state, x, y, yaw, course, dt, VX_MAX, YAW_RANGE, np)
    return state, float(vx), float(w)


def test_walking_commands_the_capped_speed_and_a_clipped_wrapped_yaw_rate() -> None:
    start = course_start(np)
    cases = [
        # (y, yaw) -> yaw rate: yaw_gain * (atan2(-y, lookahead) - yaw), wrapped, clipped to +-0.5
        ((0.0, 0.0), 0.0),
        ((0.1, 0.0), 2.0 * math.atan2(-0.1, 1.0)),  # -0.19934: steer back to the centre line
        ((-0.1, 0.0), 2.0 * math.atan2(0.1, 1.0)),
        ((0.0, 0.1), -0.2),  # heading off by 0.1 rad: turn back
        ((0.3, 0.0), -0.5),  # 2 * -0.2915 = -0.583: clipped to the policy's range
        ((0.0, -2.0), 0.5),
        ((0.0, 0.1 - 2.0 * math.pi), -0.2),  # the same heading one turn around: the error wrapped, not -12.4
        ((0.0, math.pi - 0.05), -0.5),  # almost backwards: -(pi - 0.05), clipped
        ((0.3, math.pi - 0.05), 0.5),  # -0.29 - 3.09 = -3.38 is +2.90 the short way round: turn left, not right
    ]
    for (y, yaw), expected in cases:
        state, vx, w = _step(start, 0.5, y, yaw)
        assert vx == VX_MAX  # the course's 0.8 m/s capped at the policy's 0.7
        assert w == pytest.approx(expected, abs=1e-12), (y, yaw)
        assert tuple(float(v) for v in state) == (0.0, 0.0, 0.0)  # mid-leg: nothing changes
    # a slower course than the policy's range is commanded as it is
    slow = CourseSettings(leg_m=1.0, dwell_s=0.5, speed_m_per_s=0.4, legs=2)
    assert _step(start, 0.5, 0.0, 0.0, slow)[1] == 0.4


def test_a_leg_end_starts_the_dwell_and_the_next_leg_follows_it() -> None:
    # dt 0.125 s and a 0.5 s dwell (exact in binary): the reaching step and four dwell steps stand
    course, dt = CourseSettings(leg_m=1.0, dwell_s=0.5, speed_m_per_s=0.8, legs=2), 0.125
    walk = (VX_MAX, 0.0)
    # (x at the step) -> (vx, yaw rate), (leg, dwell left s, legs done), finished after the step
    expected = [
        (0.90, walk, (0, 0.0, 0), False),
        (1.00, (0.0, 0.0), (0, 0.5, 1), False),  # the leg end: stand
        (1.00, (0.0, 0.0), (0, 0.375, 1), False),
        (1.00, (0.0, 0.0), (0, 0.25, 1), False),
        (1.00, (0.0, 0.0), (0, 0.125, 1), False),
        (1.00, (0.0, 0.0), (1, 0.0, 1), False),  # the dwell over: the second leg
        (1.00, walk, (1, 0.0, 1), False),
        (1.90, walk, (1, 0.0, 1), False),
        (2.05, (0.0, 0.0), (1, 0.5, 2), False),  # the last leg's end: walked, not finished until its dwell is
        (2.05, (0.0, 0.0), (1, 0.375, 2), False),
        (2.05, (0.0, 0.0), (1, 0.25, 2), False),
        (2.05, (0.0, 0.0), (1, 0.125, 2), False),
        (2.05, (0.0, 0.0), (2, 0.0, 2), True),
    ]
    state_np, state_j = course_start(np), course_start(jnp)
    step_j = jax.jit(lambda s, x: course_command(s, x, 0.0, 0.0, course, dt, VX_MAX, YAW_RANGE, jnp))
    for t, (x, command, (leg, dwell, done), finished) in enumerate(expected):
        state_np, vx, w = _step(state_np, x, 0.0, 0.0, course, dt)
        state_j, vx_j, w_j = step_j(state_j, jnp.float32(x))
        for state, got, xp in ((state_np, (vx, w), np), (state_j, (float(vx_j), float(w_j)), jnp)):
            assert got == pytest.approx(command, abs=1e-6), (t, xp.__name__)
            assert (float(state.leg), float(state.dwell_left_s), float(state.legs_done)) == (leg, dwell, done), t
            assert bool(course_finished(state, course, xp)) is finished, (t, xp.__name__)


def test_without_a_dwell_the_next_leg_starts_at_once_and_legs_zero_never_finishes() -> None:
    course = CourseSettings(leg_m=1.0, dwell_s=0.0, speed_m_per_s=0.8, legs=1)
    state, vx, _ = _step(course_start(np), 1.2, 0.0, 0.0, course)
    assert vx == VX_MAX  # no standing: it walks on
    assert (float(state.leg), float(state.dwell_left_s), float(state.legs_done)) == (1.0, 0.0, 1.0)
    assert bool(course_finished(state, course, np))
    endless = CourseSettings(leg_m=1.0, dwell_s=0.0, speed_m_per_s=0.8, legs=0)
    state = course_start(np)
    for x in np.arange(0.5, 50.0, 0.5):
        state, vx, _ = _step(state, float(x), 0.0, 0.0, endless)
        assert vx == VX_MAX and not bool(course_finished(state, endless, np))
    assert float(state.legs_done) == 49.0


def _trajectory(t: int, offset: float) -> tuple[float, float]:
    """(y, yaw) of a robot drifting sideways with a heading error (``offset``: one robot of a batch)."""
    return 0.3 * math.sin(0.05 * t + offset), 0.4 * math.cos(0.03 * t + 2.0 * offset)


def test_scripted_course_commands_alike_in_numpy_jax_and_a_batch() -> None:
    offsets = np.array([0.0, 0.7, 1.9, 3.1])
    speeds = np.array([1.0, 0.8, 1.2, 0.5])  # each robot covers ground at its own pace: dwells at different times
    n = len(offsets)
    state_np, state_j, state_b = course_start(np), course_start(jnp), course_start(np, (n,))
    assert all(part.shape == (n,) for part in state_b)
    step_j = jax.jit(lambda s, x, y, yaw: course_command(s, x, y, yaw, COURSE, DT, VX_MAX, YAW_RANGE, jnp))
    x, x_b = 0.0, np.zeros(n)
    alone = [course_start(np) for _ in range(n)]
    dwelling, finished_at, mixed = 0, None, set()
    for t in range(400):
        y, yaw = _trajectory(t, 0.0)
        state_np, vx, w = _step(state_np, x, y, yaw)
        state_j, vx_j, w_j = step_j(state_j, jnp.float32(x), jnp.float32(y), jnp.float32(yaw))
        assert abs(float(vx_j) - vx) < 1e-6 and abs(float(w_j) - w) < 1e-5, t
        assert bool(course_finished(state_j, COURSE, jnp)) == bool(course_finished(state_np, COURSE, np)), t
        assert float(state_j.legs_done) == float(state_np.legs_done) and float(state_j.leg) == float(state_np.leg), t
        dwelling += float(state_np.dwell_left_s) > 0.0
        if finished_at is None and bool(course_finished(state_np, COURSE, np)):
            finished_at = t
        x += vx * DT
        # the batch: every robot in one call, each row as that robot alone
        ys, yaws = zip(*(_trajectory(t, o) for o in offsets), strict=True)
        state_b, vx_b, w_b = course_command(state_b, x_b, np.array(ys), np.array(yaws), COURSE, DT, VX_MAX,
                                            YAW_RANGE, np)
        assert vx_b.shape == w_b.shape == (n,)
        for i in range(n):
            alone[i], vx_i, w_i = _step(alone[i], float(x_b[i]), ys[i], yaws[i])
            assert (vx_b[i], w_b[i]) == (vx_i, w_i), (t, i)
            assert tuple(float(p[i]) for p in state_b) == tuple(float(p) for p in alone[i]), (t, i)
        np.testing.assert_array_equal(course_finished(state_b, COURSE, np),
                                      [bool(course_finished(s, COURSE, np)) for s in alone])
        x_b += vx_b * speeds * DT
        stood, done = state_b.dwell_left_s > 0.0, course_finished(state_b, COURSE, np)
        mixed |= {"dwell"} if stood.any() and not stood.all() else set()
        mixed |= {"finish"} if done.any() and not done.all() else set()
    # two dwells of 0.5 s stood (25 control steps each) and the course finished
    assert dwelling >= 2 * 24 and finished_at is not None
    # the batch's rows were at different points: some standing while others walked, some finished before others
    assert mixed == {"dwell", "finish"}


def _quat(yaw: float, pitch: float, roll: float) -> np.ndarray:
    """(w, x, y, z) of ``Rz(yaw) Ry(pitch) Rx(roll)``."""
    cy, sy, cp, sp, cr, sr = (f(a / 2.0) for a in (yaw, pitch, roll) for f in (math.cos, math.sin))
    return np.array([cr * cp * cy + sr * sp * sy, sr * cp * cy - cr * sp * sy,
                     cr * sp * cy + sr * cp * sy, cr * cp * sy - sr * sp * cy])


def test_heading_yaw_is_the_yaw_of_the_rotation_alone_and_over_a_batch() -> None:
    rng = np.random.default_rng(0)
    angles = np.column_stack([rng.uniform(-math.pi + 1e-3, math.pi - 1e-3, 20), rng.uniform(-1.2, 1.2, 20),
                              rng.uniform(-math.pi, math.pi, 20)])
    quats = np.stack([_quat(*a) for a in angles])
    for (yaw, _, _), q in zip(angles, quats, strict=True):
        assert float(heading_yaw(q, np)) == pytest.approx(yaw, abs=1e-12)
        assert float(heading_yaw(-q, np)) == pytest.approx(yaw, abs=1e-12)  # q and -q: one rotation
    np.testing.assert_allclose(heading_yaw(quats, np), angles[:, 0], atol=1e-12)
    np.testing.assert_allclose(np.asarray(jax.jit(lambda q: heading_yaw(q, jnp))(jnp.asarray(quats, jnp.float32))),
                               angles[:, 0], atol=1e-5)
