"""The card robots' fall rule (couriers/physics.has_fallen), the same in NumPy (the walker env) and JAX
(the mjx humanoid couriers): tilt, height, and the runaway rule that ends a blow-up as a fall."""

from __future__ import annotations

import math

import jax.numpy as jnp
import numpy as np
import pytest

from econmotor.couriers.physics import has_fallen
from econmotor.robots import CARDS

CARD = CARDS["g1_29dof"]


def state(tilt_rad: float = 0.0, z: float | None = None, speed: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    qpos = np.zeros(7 + CARD.num_dofs)
    qpos[2] = CARD.init_pos[2] if z is None else z
    qpos[3:7] = (math.cos(tilt_rad / 2), math.sin(tilt_rad / 2), 0.0, 0.0)
    qvel = np.zeros(6 + CARD.num_dofs)
    qvel[0] = speed
    return qpos, qvel


CASES = [  # (state, fell)
    (state(), False),
    (state(speed=1.5), False),  # walking, even pushed
    (state(tilt_rad=CARD.fall_tilt_rad + 0.01), True),
    (state(z=CARD.min_base_z_m - 0.01), True),
    (state(speed=CARD.runaway_speed_m_per_s + 1.0), True),  # upright, blown up
]


@pytest.mark.parametrize("xp", [np, jnp], ids=["numpy", "jax"])
def test_each_rule_alone_decides_a_fall(xp):
    for (qpos, qvel), fell in CASES:
        assert bool(has_fallen(CARD, xp.asarray(qpos), xp.asarray(qvel), xp)) is fell


def test_a_non_finite_state_is_a_fall_and_a_batch_is_judged_row_by_row():
    (qpos, qvel), _ = CASES[0]
    bad = qvel.copy()
    bad[7] = np.nan
    rows = has_fallen(CARD, np.stack([qpos, qpos, CASES[4][0][0]]), np.stack([qvel, bad, CASES[4][0][1]]), np)
    assert rows.tolist() == [False, True, True]
    assert not has_fallen(CARD, *CASES[4][0], np, runaway_speed_m_per_s=100.0)  # the threshold is the caller's
