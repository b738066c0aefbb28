"""The course as pure functions (couriers/course.py) commands what the sim-to-sim evaluator's controller does.

A scripted trajectory (walking along x with a lateral drift and a heading error, standing at each
leg end) is fed to both, step by step: the same commands, dwell and finish, in NumPy and in JAX.
"""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from econmotor.couriers.course import (
    CourseSettings,
    course_command,
    course_finished,
    course_start,
    heading_yaw,
)
from econmotor.motor_backend.holosoma.sim2sim import CourseController, _yaw

COURSE = CourseSettings(leg_m=1.0, dwell_s=0.5, speed_m_per_s=0.8, legs=2)
DT = 0.02
RANGES = {"lin_vel_x": [-1.0, 0.7], "ang_vel_yaw": [-0.5, 0.5]}


def test_course_functions_command_as_the_evaluators_controller() -> None:
    controller = CourseController(COURSE, DT, RANGES)
    state_np, state_j = course_start(np), course_start(jnp)
    step_j = jax.jit(lambda s, x, y, yaw: course_command(s, x, y, yaw, COURSE, DT, 0.7, (-0.5, 0.5), jnp))
    x, seen_dwell, finished_at = 0.0, 0, None
    for t in range(400):
        y, yaw = 0.3 * math.sin(0.05 * t), 0.4 * math.cos(0.03 * t)
        vx, w = controller.command(x, y, yaw)
        state_np, vx_np, w_np = course_command(state_np, x, y, yaw, COURSE, DT, 0.7, (-0.5, 0.5), np)
        state_j, vx_j, w_j = step_j(state_j, jnp.float32(x), jnp.float32(y), jnp.float32(yaw))
        assert float(vx_np) == vx and float(w_np) == pytest.approx(w, abs=1e-12), t
        assert abs(float(vx_j) - vx) < 1e-6 and abs(float(w_j) - w) < 1e-5, t
        assert bool(course_finished(state_np, COURSE, np)) == controller.finished
        assert bool(course_finished(state_j, COURSE, jnp)) == controller.finished
        seen_dwell += controller.dwelling
        if controller.finished and finished_at is None:
            finished_at = t
        x += vx * DT
    assert seen_dwell > 40 and finished_at is not None  # two dwells stood, the course finished


def test_heading_yaw_is_the_evaluators() -> None:
    rng = np.random.default_rng(0)
    for _ in range(20):
        q = rng.normal(size=4)
        q /= np.linalg.norm(q)
        assert float(heading_yaw(q, np)) == pytest.approx(_yaw(q), abs=1e-12)
