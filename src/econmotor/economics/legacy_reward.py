"""The legacy training-economics reward (spec: RewardBuilder integration §1).

``r(t) = alpha*dMP_r(t) - beta*e(t) - gamma*|w_r(t)/w_h - 1|``

``MP_r(t)`` is the running throughput (good units so far / hours so far) and
``dMP_r(t) = MP_r(t) - MP_r(t-1)`` with ``MP_r(0) = 0``, so the episode sum of the
first term telescopes to ``alpha * MPL_episode``. ``e(t)`` is the step's error
rate and ``w_r(t)`` the step's implied wage.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class LegacyRewardWeights:
    """alpha (per unit/h of MPL change), beta (per unit of error rate), gamma (per unit of wage gap)."""

    alpha: float = 1.0
    beta: float = 1.0
    gamma: float = 0.1


def compute_econ_reward(
    d_mpl: float,
    err_rate: float,
    robot_wage: float,
    human_wage: float,
    weights: LegacyRewardWeights = LegacyRewardWeights(),
) -> float:
    """``alpha*d_mpl - beta*err_rate - gamma*|robot_wage/human_wage - 1|``.

    Args:
        d_mpl: change of the running MPL this step, units/h.
        err_rate: this step's errors / attempts.
        robot_wage: this step's implied robot wage, USD/h.
        human_wage: human wage, USD/h (> 0).
        weights: alpha, beta, gamma.
    """
    if human_wage <= 0:
        raise ValueError(f"human_wage must be > 0, got {human_wage}")
    return (
        weights.alpha * d_mpl
        - weights.beta * err_rate
        - weights.gamma * abs(robot_wage / human_wage - 1.0)
    )
