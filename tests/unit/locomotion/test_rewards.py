"""Holosoma's locomotion terms (locomotion/rewards.py): hand-worked values of one env, alike in NumPy and JAX,
and over a batch of robots one value per robot, each the one the robot's own reading gives.

The MJX humanoid env calls the terms on one env (jnp); the mujoco walker trainer on a batch (NumPy, a
leading robot axis): both engines pay the same terms.
"""

from __future__ import annotations

import math

import jax.numpy as jnp
import numpy as np
import pytest

from econmotor.locomotion import rewards as lr

PARAMS = {"feet_phase": {"swing_height": 0.09, "tracking_sigma": 0.008},
          "pose": {"pose_weights": [0.5, 1.0, 5.0]},
          "penalty_close_feet_xy": {"close_feet_threshold": 0.15}}


def _batch(n: int, seed: int = 0) -> lr.LocomotionReading:
    """``n`` robots' readings (3 joints): random, the feet of every other robot close across its heading
    (one ahead of the other), the others' 0.3 m apart across it."""
    rng = np.random.default_rng(seed)
    feet_xy = rng.uniform(-0.3, 0.3, (n, 2, 2))
    yaw = rng.uniform(-math.pi, math.pi, n)
    along, across = np.stack([np.cos(yaw), np.sin(yaw)], axis=-1), np.stack([-np.sin(yaw), np.cos(yaw)], axis=-1)
    feet_xy[:, 1] = feet_xy[:, 0] + np.where(np.arange(n)[:, None] % 2 == 0, 0.3 * along, 0.3 * across)
    return lr.LocomotionReading(
        command=rng.uniform(-1, 1, (n, 3)), lin_vel_body=rng.uniform(-1, 1, (n, 3)),
        ang_vel_body=rng.uniform(-1, 1, (n, 3)), gravity_body=rng.uniform(-0.2, 0.2, (n, 3)),
        action=rng.uniform(-1, 1, (n, 3)), last_action=rng.uniform(-1, 1, (n, 3)), q=rng.uniform(-1, 1, (n, 3)),
        default_q=np.array([0.1, -0.2, 0.3]), phase=rng.uniform(-math.pi, math.pi, (n, 2)),
        foot_z=rng.uniform(0.0, 0.1, (n, 2)), feet_xy=feet_xy, feet_gravity_xy=rng.uniform(-0.3, 0.3, (n, 2, 2)),
        base_yaw=yaw)


def _robot(r: lr.LocomotionReading, i: int) -> lr.LocomotionReading:
    return r._replace(**{k: v[i] for k, v in r._asdict().items() if k != "default_q"})


@pytest.mark.parametrize("name", list(lr.TERMS))
def test_a_batch_gives_each_robot_its_own_value(name: str) -> None:
    n, batch = 6, _batch(6)
    term = lr.TERMS[name]
    values = np.broadcast_to(term(batch, np, **PARAMS.get(name, {})), (n,))
    alone = [float(term(_robot(batch, i), np, **PARAMS.get(name, {}))) for i in range(n)]
    np.testing.assert_allclose(values, alone, rtol=1e-12, atol=0)
    if name == "penalty_close_feet_xy":  # both cases held: the close robots and the others
        assert list(values) == [1.0, 0.0] * 3


@pytest.mark.parametrize("xp", [np, jnp], ids=["numpy", "jax"])
def test_one_env_hand_worked(xp) -> None:
    r = lr.LocomotionReading(
        command=xp.asarray([0.5, 0.0, 0.2]), lin_vel_body=xp.asarray([0.4, 0.1, 0.0]),
        ang_vel_body=xp.asarray([0.1, -0.2, 0.3]), gravity_body=xp.asarray([0.0, 0.1, -0.99]),
        action=xp.asarray([0.5, 0.0]), last_action=xp.asarray([0.0, 0.0]), q=xp.asarray([0.2, 0.0, 1.0]),
        default_q=xp.asarray([0.0, 0.0, 0.5]), phase=xp.asarray([0.0, -math.pi]),
        foot_z=xp.asarray([0.09, 0.01]), feet_xy=xp.asarray([[0.0, 0.1], [0.3, 0.0]]),
        feet_gravity_xy=xp.asarray([[0.3, 0.4], [0.0, 0.0]]), base_yaw=xp.asarray(math.pi / 2))
    # phase 0: x = 1/2, the swing's top (0.09); phase -pi: x = 0, on the floor
    assert float(lr.feet_phase(r, xp, swing_height=0.09, tracking_sigma=0.008)) == pytest.approx(
        math.exp(-0.01 ** 2 / 0.008), rel=1e-6)
    assert float(lr.pose(r, xp, pose_weights=[1.0, 2.0, 4.0])) == pytest.approx(0.04 + 4 * 0.25, rel=1e-6)
    assert float(lr.pose(r, xp)) == pytest.approx(0.04 + 0.25, rel=1e-6)
    # heading +y: across it is x; the feet 0.3 apart in x
    assert float(lr.penalty_close_feet_xy(r, xp, close_feet_threshold=0.15)) == 0.0
    assert float(lr.penalty_close_feet_xy(r, xp, close_feet_threshold=0.35)) == 1.0
    assert float(lr.penalty_feet_ori(r, xp)) == pytest.approx(0.5, rel=1e-6)
    for name, term in lr.TERMS.items():
        assert np.shape(term(r, xp, **PARAMS.get(name, {}))) == (), name
