import pytest

from econmotor.errors import ConfigError
from econmotor.objectives import EconomicObjectiveSpec, compile_economic_overlay


def test_spec_example_compiles_to_documented_scales():
    spec = EconomicObjectiveSpec(
        mpl_weight=1.0, energy_weight=0.2, error_weight=0.5, novelty_weight=0.0, risk_weight=0.3,
        extra_weights={"stability_margin": -0.1},
    )
    assert compile_economic_overlay(spec).to_dict() == {
        "mpl_per_hour": 1.0, "energy_kwh": -0.2, "error_rate": -0.5, "risk_score": -0.3, "stability_margin": -0.1,
    }


def test_penalty_weights_are_negative_whatever_their_sign():
    overlay = compile_economic_overlay(EconomicObjectiveSpec(energy_weight=-2.0, error_weight=-3.0, risk_weight=4.0))
    assert overlay["energy_kwh"] == -2.0
    assert overlay["error_rate"] == -3.0
    assert overlay["risk_score"] == -4.0


def test_mpl_and_novelty_keep_their_sign():
    overlay = compile_economic_overlay(EconomicObjectiveSpec(mpl_weight=-1.5, novelty_weight=-0.5))
    assert overlay["mpl_per_hour"] == -1.5
    assert overlay["novelty_score"] == -0.5


def test_overlay_weighted_sum():
    overlay = compile_economic_overlay(EconomicObjectiveSpec(mpl_weight=2.0, energy_weight=1.0))
    assert overlay.weighted_sum({"mpl_per_hour": 10.0, "energy_kwh": 3.0}) == pytest.approx(17.0)


def test_spec_is_frozen_and_hashable():
    spec = EconomicObjectiveSpec(extra_weights={"a": 1.0})
    with pytest.raises(AttributeError):
        spec.mpl_weight = 3.0  # type: ignore[misc]
    with pytest.raises(TypeError):
        spec.extra_weights["b"] = 2.0  # type: ignore[index]
    assert hash(spec) == hash(EconomicObjectiveSpec(extra_weights={"a": 1.0}))


@pytest.mark.parametrize("bad", [float("nan"), float("inf"), "1.0", True])
def test_non_finite_or_non_numeric_weights_rejected(bad):
    with pytest.raises(ConfigError, match="mpl_weight"):
        EconomicObjectiveSpec(mpl_weight=bad)
