"""Lagrange multipliers: rise while violated, fall back when met, never below 0."""

from __future__ import annotations

import itertools

import pytest

from econmotor.errors import ConfigError
from econmotor.rl.constraint_shaping import ConstraintShaper
from econmotor.rl.lagrange import LagrangeMultipliers, signed_costs
from econmotor.valuation import ConstraintSet


def test_multiplier_rises_while_violated_and_falls_back_to_zero_when_met():
    lag = LagrangeMultipliers(("max_error_rate",), lr=2.0)
    values = []
    for _ in range(5):  # error rate 0.10 against a 0.05 cap
        lag.record({"max_error_rate": 0.05})
        values.append(lag.update()["max_error_rate"])
    assert values == pytest.approx([0.1, 0.2, 0.3, 0.4, 0.5])
    for _ in range(10):  # now 0.02 against 0.05: slack of 0.03
        lag.record({"max_error_rate": -0.03})
        values.append(lag.update()["max_error_rate"])
    assert values[5] == pytest.approx(0.44)
    assert all(b <= a for a, b in itertools.pairwise(values[4:]))
    assert values[-1] == 0.0
    assert len(lag.history) == 15


def test_update_uses_the_mean_over_recorded_episodes_and_respects_the_cap():
    lag = LagrangeMultipliers(("min_wage_parity", "max_error_rate"), lr=1.0, upper=0.5)
    lag.record({"min_wage_parity": 0.2, "max_error_rate": 1.0})
    lag.record({"min_wage_parity": -0.1, "max_error_rate": 1.0})
    out = lag.update()
    assert out["min_wage_parity"] == pytest.approx(0.05)
    assert out["max_error_rate"] == 0.5
    assert lag.penalty({"min_wage_parity": 2.0, "max_error_rate": -1.0}) == pytest.approx(0.1 - 0.5)


def test_signed_costs_are_positive_when_violated_for_minimums_and_maximums():
    cs = ConstraintSet(min_wage_parity=0.9, max_error_rate=0.05, max_energy_Wh=10.0, energy_basis="per_episode")
    costs = signed_costs(cs, {"wage_parity": 0.7, "error_rate": 0.02, "energy_Wh": 12.0})
    assert costs == pytest.approx({"min_wage_parity": 0.2, "max_error_rate": -0.03, "max_energy_Wh": 2.0})


def test_bad_settings_are_config_errors():
    with pytest.raises(ConfigError, match="lr"):
        LagrangeMultipliers(("max_error_rate",), lr=-1.0)
    lag = LagrangeMultipliers(("max_error_rate",))
    with pytest.raises(ConfigError, match="no multiplier"):
        lag.record({"max_energy_Wh": 1.0})
    with pytest.raises(ConfigError, match="no active constraint"):
        ConstraintShaper(ConstraintSet(), "penalty")
    with pytest.raises(ConfigError, match="lagrangian"):
        ConstraintShaper(ConstraintSet(max_error_rate=0.1), "dual")
