import pytest

from econmotor.economics import LegacyRewardWeights, compute_econ_reward


def test_formula_on_worked_values():
    # r = alpha*dMP - beta*e - gamma*|w_r/w_h - 1| = 2*3 - 0.5*0.1 - 4*|9/18 - 1| = 6 - 0.05 - 2
    w = LegacyRewardWeights(alpha=2.0, beta=0.5, gamma=4.0)
    assert compute_econ_reward(3.0, 0.1, 9.0, 18.0, w) == pytest.approx(3.95)


def test_wage_gap_is_symmetric_and_zero_at_parity():
    w = LegacyRewardWeights(alpha=0.0, beta=0.0, gamma=1.0)
    assert compute_econ_reward(0.0, 0.0, 18.0, 18.0, w) == 0.0
    assert compute_econ_reward(0.0, 0.0, 27.0, 18.0, w) == pytest.approx(-0.5)
    assert compute_econ_reward(0.0, 0.0, 9.0, 18.0, w) == pytest.approx(-0.5)


def test_rejects_non_positive_human_wage():
    with pytest.raises(ValueError):
        compute_econ_reward(1.0, 0.0, 1.0, 0.0)


def test_a_small_positive_human_wage_is_accepted_and_the_refusal_says_the_value():
    # wage 0.5 USD/h, robot 1.0: gap |2 - 1| = 1, times gamma 0.1
    assert compute_econ_reward(0.0, 0.0, 1.0, 0.5, LegacyRewardWeights()) == pytest.approx(-0.1)
    with pytest.raises(ValueError, match=r"human_wage must be > 0, got -2\.0"):
        compute_econ_reward(0.0, 0.0, 1.0, -2.0)
