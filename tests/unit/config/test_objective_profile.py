import pytest

from econmotor.config.objective_profile import OBJECTIVE_PRESETS, EconContext, ObjectiveVector, RewardWeights
from econmotor.errors import ConfigError


def test_six_presets_as_designed():
    assert {k: list(v) for k, v in OBJECTIVE_PRESETS.items()} == {
        "throughput": [2, 1, 0.5, 1, 0],
        "safety": [0.5, 2, 1, 3, 0],
        "energy_saver": [1, 1, 3, 1, 0],
        "balanced": [1, 1, 1, 1, 0],
        "throughput_focused": [3, 0.5, 0.3, 0.5, 0],
        "premium_safety": [1, 3, 1, 5, 0],
    }
    for name, values in OBJECTIVE_PRESETS.items():
        assert ObjectiveVector.from_preset(name).to_list() == list(values)


def test_list_round_trip_and_normalize():
    vec = ObjectiveVector.from_list([2, 1, 0.5, 1, 0])
    assert vec.to_list() == [2.0, 1.0, 0.5, 1.0, 0.0]
    norm = vec.normalize()
    assert sum(norm.to_list()) == pytest.approx(1.0)
    assert norm.w_mpl == pytest.approx(2 / 4.5)


def test_normalize_all_zero_is_an_error():
    with pytest.raises(ConfigError):
        ObjectiveVector(0, 0, 0, 0, 0).normalize()


@pytest.mark.parametrize("values", [[1, 2, 3], [1, 2, 3, 4, -1], [1, 2, 3, 4, float("nan")], "abcde"])
def test_from_list_rejects_bad_vectors(values):
    with pytest.raises(ConfigError):
        ObjectiveVector.from_list(values)


def test_econ_context_defaults():
    ctx = EconContext()
    assert (ctx.wage_human, ctx.energy_price_kWh, ctx.market_region, ctx.task_family, ctx.customer_segment,
            ctx.baseline_mpl_human, ctx.baseline_error_human) == (
        18.0, 0.12, "US", "dishwashing", "balanced", 60.0, 0.05)
    with pytest.raises(ConfigError, match="wage_human"):
        EconContext(wage_human=-1.0)


def test_reward_weights_follow_the_spec_order_with_alpha_ep():
    # spec §4: [alpha_mpl, alpha_ep, alpha_error, alpha_energy, alpha_safety]; novelty comes after
    w = RewardWeights.from_list([1, 2, 3, 4, 5])
    assert (w.alpha_mpl, w.alpha_ep, w.alpha_error, w.alpha_energy, w.alpha_safety, w.alpha_novelty) == (
        1, 2, 3, 4, 5, 0)
    assert w.to_list() == [1, 2, 3, 4, 5, 0]
    assert RewardWeights.from_list(w.to_list()) == w
    assert RewardWeights().alpha_ep == 0.0
    identity = RewardWeights.from_objective(ObjectiveVector.from_preset("energy_saver"))
    assert identity.to_list() == [1, 0, 1, 3, 1, 0]
    with pytest.raises(ConfigError, match="alpha_ep"):
        RewardWeights.from_list([1, 2, 3])
    with pytest.raises(ConfigError, match="alpha_ep"):
        RewardWeights(alpha_ep=float("nan"))


def test_energy_term_option_is_wh_by_default_and_validated():
    assert ObjectiveVector().energy_term == "wh"
    assert ObjectiveVector.from_preset("energy_saver").energy_term == "wh"
    priced = ObjectiveVector.from_preset("energy_saver", energy_term="usd")
    assert priced.to_list() == [1, 1, 3, 1, 0] and priced.normalize().energy_term == "usd"
    with pytest.raises(ConfigError, match="energy_term"):
        ObjectiveVector(energy_term="kwh")
