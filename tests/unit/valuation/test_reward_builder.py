import pytest

from econmotor.config.econ_params import EconParams
from econmotor.config.objective_profile import ObjectiveVector
from econmotor.valuation import build_reward_terms, combine_reward, default_objective_vector

GOOD = {"mpl": 60.0, "error_rate": 0.02, "energy_Wh": 15.0, "termination_reason": "max_steps"}
BAD = {"mpl": 20.0, "error_rate": 0.3, "energy_Wh": 40.0, "termination_reason": "catastrophic_error"}


def test_default_vector():
    assert default_objective_vector() == [1.0, 0.2, 0.1, 0.05, 0.0]


def test_spec_sanity_check_good_and_bad_episode():
    # spec §7 check 1: 60 - 0.2*0.02 - 0.1*15 = 58.496 ; 20 - 0.2*0.3 - 0.1*40 - 0.05 = 15.89
    assert combine_reward(default_objective_vector(), build_reward_terms(GOOD)) == pytest.approx(58.496)
    assert combine_reward(default_objective_vector(), build_reward_terms(BAD)) == pytest.approx(15.89)


def test_terms_with_an_electricity_price():
    params = EconParams(energy_price_usd_per_kwh=0.12)
    terms = build_reward_terms({**GOOD, "novelty": 0.5}, params)
    assert terms == pytest.approx({"r_mpl": 60.0, "r_error": -0.02, "r_energy": -0.0018, "r_safety": 0.0,
                                   "r_novelty": 0.5})


def test_episode_field_names_and_objects_are_read():
    class Summary:
        mpl_episode = 30.0
        error_rate_episode = 0.1
        energy_Wh = 2.0
        termination_reason = "catastrophic_error"
        novelty_score = 0.25

    terms = build_reward_terms(Summary())
    assert terms == {"r_mpl": 30.0, "r_error": -0.1, "r_energy": -2.0, "r_safety": -1.0, "r_novelty": 0.25}


def test_presets_order_good_over_bad_and_accept_objective_vectors():
    for name in ("throughput", "safety", "energy_saver"):
        vec = ObjectiveVector.from_preset(name)
        assert combine_reward(vec, build_reward_terms(GOOD)) > combine_reward(vec, build_reward_terms(BAD))


def test_combine_reward_needs_five_weights():
    with pytest.raises(ValueError):
        combine_reward([1.0, 2.0], build_reward_terms(GOOD))
