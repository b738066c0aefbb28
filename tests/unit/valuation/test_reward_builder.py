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


def test_incremental_terms_sum_to_the_episode_terms_of_recorded_counts():
    from econmotor.valuation.reward_builder import IncrementalRewardTerms

    # three 1-minute steps: (good units, errors, Wh); the shift ends in a catastrophe
    counts = [(2, 0, 0.1), (0, 0, 0.05), (1, 2, 0.15)]
    reasons = [None, None, "catastrophic_error"]
    novelty_running = [0.5, 0.25, 0.5]
    price = EconParams(energy_price_usd_per_kwh=0.12)
    incremental, sums, units = IncrementalRewardTerms(), {}, 0
    for t, ((u, e, wh), reason, nov) in enumerate(zip(counts, reasons, novelty_running, strict=True), start=1):
        units += u
        step = {"mpl_t": units / (t / 60.0), "errors": e, "attempts": u + e, "Wh": wh,
                "termination_reason": reason, "novelty_running": nov, "catastrophic": e > 0 and u == 0}
        for name, value in incremental.step(step, price).items():
            sums[name] = sums.get(name, 0.0) + value
    # the episode by hand: 3 units in 3 minutes, 2 errors in 5 attempts, 0.3 Wh at $0.12/kWh
    assert sums == pytest.approx({"r_mpl": 60.0, "r_error": -0.4, "r_energy": -0.3 * 0.12 / 1000.0,
                                  "r_safety": -1.0, "r_novelty": 0.5})
    episode = {"mpl": 60.0, "error_rate": 0.4, "energy_Wh": 0.3, "termination_reason": "catastrophic_error",
               "novelty": 0.5}
    assert sums == pytest.approx(build_reward_terms(episode, price))


def test_incremental_safety_fires_once_and_reset_starts_a_new_episode():
    from econmotor.valuation.reward_builder import IncrementalRewardTerms

    incremental = IncrementalRewardTerms()
    step = {"mpl_t": 30.0, "errors": 1, "attempts": 1, "Wh": 2.0, "vase_broken": True,
            "overlay_terms": {"novelty_score": 0.04}}
    first, second = incremental.step(step), incremental.step(step)
    assert (first["r_safety"], second["r_safety"]) == (-1.0, 0.0)
    assert (first["r_mpl"], second["r_mpl"]) == (30.0, 0.0)
    assert first["r_energy"] == -2.0 and first["r_novelty"] == 0.04  # no price: Wh; overlay novelty increment
    incremental.reset()
    assert incremental.step({**step, "errors": 0})["r_safety"] == -1.0
    with pytest.raises(ValueError, match="attempts"):
        incremental.step({"mpl_t": 1.0, "errors": 0})
