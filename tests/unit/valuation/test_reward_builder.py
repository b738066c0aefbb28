import math

import pytest

from econmotor.config.econ_params import EconParams
from econmotor.config.objective_profile import ObjectiveVector
from econmotor.errors import ConfigError
from econmotor.valuation import build_reward_terms, combine_reward, default_objective_vector, extract_step_summary
from econmotor.valuation.reward_builder import IncrementalRewardTerms, reward_terms_from_metrics

GOOD = {"mpl": 60.0, "error_rate": 0.02, "energy_Wh": 15.0, "termination_reason": "max_steps"}
BAD = {"mpl": 20.0, "error_rate": 0.3, "energy_Wh": 40.0, "termination_reason": "catastrophic_error"}


def test_default_vector():
    assert default_objective_vector() == [1.0, 0.2, 0.1, 0.05, 0.0]


def test_spec_sanity_check_good_and_bad_episode():
    # spec §7 check 1: 60 - 0.2*0.02 - 0.1*15 = 58.496 ; 20 - 0.2*0.3 - 0.1*40 - 0.05 = 15.89
    assert combine_reward(default_objective_vector(), build_reward_terms(GOOD)) == pytest.approx(58.496)
    assert combine_reward(default_objective_vector(), build_reward_terms(BAD)) == pytest.approx(15.89)


def test_the_energy_term_is_wh_on_a_priced_task_and_usd_only_when_the_objective_asks():
    params = EconParams(energy_price_usd_per_kwh=0.12)
    terms = build_reward_terms({**GOOD, "novelty": 0.5, "ep_episode": 400.0}, params)
    assert terms == pytest.approx({"r_mpl": 60.0, "r_ep": 400.0, "r_error": -0.02, "r_energy": -15.0,
                                   "r_safety": 0.0, "r_novelty": 0.5})
    priced = build_reward_terms({**GOOD, "novelty": 0.5}, params, energy_term="usd")
    assert priced["r_energy"] == pytest.approx(-0.0018)
    # spec §7 check 1 holds on a priced task too (the price no longer enters by default)
    assert combine_reward(default_objective_vector(), build_reward_terms(GOOD, params)) == pytest.approx(58.496)
    assert combine_reward(default_objective_vector(), build_reward_terms(BAD, params)) == pytest.approx(15.89)
    with pytest.raises(ValueError, match="energy_price_usd_per_kwh"):
        build_reward_terms(GOOD, EconParams(), energy_term="usd")  # no price to price it with
    with pytest.raises(ValueError, match="energy_term"):
        build_reward_terms(GOOD, params, energy_term="kwh")


def test_episode_field_names_and_objects_are_read():
    class Summary:
        mpl_episode = 30.0
        error_rate_episode = 0.1
        energy_Wh = 2.0
        termination_reason = "catastrophic_error"
        novelty_score = 0.25

    terms = build_reward_terms(Summary())
    assert terms == {"r_mpl": 30.0, "r_ep": 0.0, "r_error": -0.1, "r_energy": -2.0, "r_safety": -1.0,
                     "r_novelty": 0.25}


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
    for energy_term, r_energy in (("wh", -0.3), ("usd", -0.3 * 0.12 / 1000.0)):
        incremental, sums, units, wh_so_far = IncrementalRewardTerms(), {}, 0, 0.0
        for t, ((u, e, wh), reason, nov) in enumerate(zip(counts, reasons, novelty_running, strict=True), start=1):
            units, wh_so_far = units + u, wh_so_far + wh
            step = {"mpl_t": units / (t / 60.0), "errors": e, "attempts": u + e, "Wh": wh,
                    "ep_t": units / (wh_so_far / 1000.0),
                    "termination_reason": reason, "novelty_running": nov, "catastrophic": e > 0 and u == 0}
            for name, value in incremental.step(step, price, energy_term).items():
                sums[name] = sums.get(name, 0.0) + value
        # the episode by hand: 3 units in 3 minutes, 2 errors in 5 attempts, 0.3 Wh (10,000 units/kWh)
        assert sums == pytest.approx({"r_mpl": 60.0, "r_ep": 10_000.0, "r_error": -0.4, "r_energy": r_energy,
                                      "r_safety": -1.0, "r_novelty": 0.5})
        episode = {"mpl": 60.0, "error_rate": 0.4, "energy_Wh": 0.3, "termination_reason": "catastrophic_error",
                   "novelty": 0.5, "ep_episode": 10_000.0}
        assert sums == pytest.approx(build_reward_terms(episode, price, energy_term))


def test_incremental_safety_fires_once_and_reset_starts_a_new_episode():
    from econmotor.valuation.reward_builder import IncrementalRewardTerms

    incremental = IncrementalRewardTerms()
    step = {"mpl_t": 30.0, "errors": 1, "attempts": 1, "Wh": 2.0, "vase_broken": True,
            "overlay_terms": {"novelty_score": 0.04}}
    first, second = incremental.step(step), incremental.step(step)
    assert (first["r_safety"], second["r_safety"]) == (-1.0, 0.0)
    assert (first["r_mpl"], second["r_mpl"]) == (30.0, 0.0)
    assert first["r_energy"] == -2.0 and first["r_novelty"] == 0.04  # Wh; overlay novelty increment
    incremental.reset()
    assert incremental.step({**step, "errors": 0})["r_safety"] == -1.0
    with pytest.raises(ValueError, match="attempts"):
        incremental.step({"mpl_t": 1.0, "errors": 0})


def test_episode_j_is_combine_reward_of_the_terms_under_the_objective_option():
    from econmotor.config.task_economics import TaskEconomics
    from econmotor.valuation import episode_j

    economics = TaskEconomics(energy_price_usd_per_kwh=0.12)
    assert episode_j(GOOD, default_objective_vector(), economics) == pytest.approx(58.496)
    assert episode_j(BAD, ObjectiveVector(), economics) == pytest.approx(15.89)
    priced = ObjectiveVector(energy_term="usd")
    assert episode_j(GOOD, priced, economics) == pytest.approx(60.0 - 0.2 * 0.02 - 0.1 * 15 * 0.12 / 1000)
    assert episode_j(GOOD, priced, economics, energy_term="wh") == pytest.approx(58.496)  # explicit override
    assert priced.normalize().energy_term == "usd"


def test_reward_weights_scale_energy_productivity_with_alpha_ep():
    from econmotor.config.objective_profile import RewardWeights

    terms = build_reward_terms({**GOOD, "ep_episode": 400.0})
    identity = RewardWeights.from_objective(default_objective_vector())
    assert identity.alpha_ep == 0.0
    assert combine_reward(identity, terms) == pytest.approx(58.496)
    with_ep = RewardWeights.from_list([1.0, 0.01, 0.2, 0.1, 0.05])  # spec §4 order: mpl, ep, error, energy, safety
    assert combine_reward(with_ep, terms) == pytest.approx(58.496 + 0.01 * 400.0)


def test_extract_step_summary_reads_the_info_of_a_real_step():
    from econmotor.envs import DishwashingEnv
    from econmotor.valuation import extract_step_summary

    env = DishwashingEnv()
    env.reset(seed=0)
    _, _, _, _, info = env.step([0.5, 0.5])
    summary = extract_step_summary(info)
    assert summary == info["step_summary"] and summary is not info["step_summary"]
    assert build_reward_terms(summary)["r_energy"] == -summary["Wh"]
    with pytest.raises(ValueError, match="step_summary"):
        extract_step_summary({"episode": 1})


def test_a_catastrophe_is_read_from_any_of_its_three_signs():
    calm = {**GOOD, "termination_reason": "max_steps"}
    assert build_reward_terms(calm)["r_safety"] == 0.0
    for sign in ({"catastrophic": True}, {"vase_broken": True}, {"termination_reason": "fall"}):
        assert build_reward_terms({**calm, **sign})["r_safety"] == -1.0


def test_an_infinite_energy_productivity_counts_as_none_and_other_infinite_figures_are_refused():
    # ep is inf when work was done without energy: r_ep is then 0, not inf (nor 1)
    assert build_reward_terms({**GOOD, "ep_episode": math.inf})["r_ep"] == 0.0
    with pytest.raises(ConfigError) as info:
        build_reward_terms({**GOOD, "mpl": math.inf})
    assert str(info.value) == "<summary>: key 'mpl': must be finite, got inf"


def test_the_term_formulas_default_to_wh_and_no_energy_productivity():
    terms = reward_terms_from_metrics(60.0, 0.02, 15.0, False, 0.5)
    assert terms == {"r_mpl": 60.0, "r_ep": 0.0, "r_error": -0.02, "r_energy": -15.0, "r_safety": 0.0,
                     "r_novelty": 0.5}


def test_economics_without_an_electricity_price_serve_wh_and_are_refused_for_usd():
    assert build_reward_terms(GOOD, object())["r_energy"] == -15.0  # not priced: the price is never read
    with pytest.raises(ConfigError) as info:
        build_reward_terms(GOOD, object(), energy_term="usd")
    assert str(info.value) == ("<task economics>: key 'energy_price_usd_per_kwh': the objective prices energy "
                               "(energy_term: usd) but the task has no electricity price; set one or use "
                               "energy_term: wh")


def test_bad_weights_and_a_missing_step_summary_say_what_is_expected():
    with pytest.raises(ConfigError) as info:
        combine_reward([1.0, 2.0, 3.0, 4.0, 5.0, 6.0], build_reward_terms(GOOD))
    assert str(info.value) == "<objective_vector>: expected 5 weights, got 6"
    with pytest.raises(ConfigError) as info:
        extract_step_summary([1])
    assert str(info.value) == "<info>: expected the step's info mapping, got list"
    with pytest.raises(ConfigError) as info:
        extract_step_summary({"step_summary": None})
    assert str(info.value) == ("<info>: key 'step_summary': no per-step summary in info; wrap MuJoCo envs in "
                               "econmotor.motor_backend.mujoco.step_summary.MujocoStepSummaryWrapper")


def test_incremental_error_terms_follow_the_running_rate_of_the_counts_so_far():
    # steps: 0 of 0 attempted (rate 0), 1 error in 1 (rate 1), 0 in 1 (1/2), 1 in 2 (2/4 = 1/2)
    incremental = IncrementalRewardTerms()
    rates = []
    for errors, attempts in ((0, 0), (1, 1), (0, 1), (1, 2)):
        step = incremental.step({"mpl_t": 0.0, "errors": errors, "attempts": attempts, "Wh": 0.0,
                                 "overlay_terms": {}})
        rates.append(step["r_error"])
        assert step["r_safety"] == 0.0 and step["r_novelty"] == 0.0  # no catastrophe, no novelty given
    assert rates == pytest.approx([0.0, -1.0, 0.5, 0.0])
    with pytest.raises(ConfigError) as info:
        incremental.step({"mpl_t": 1.0, "errors": 0})
    assert str(info.value) == ("<step_summary>: key 'attempts': incremental reward terms need the running MPL "
                               "and the step's counts (allowed: attempts, errors, mpl_t)")
