"""Pricing model on hand-computed worked examples (module docstring of economics/pricing.py)."""

from __future__ import annotations

import math

import pytest

from econmotor.config.task_economics import TaskEconomics
from econmotor.economics.meter import EconomicMeter
from econmotor.economics.pricing import (
    PricingPolicy,
    distribution,
    price_evaluation,
    price_from_metrics,
    price_task,
    pricing_inputs,
    quantile,
)
from econmotor.errors import ConfigError

# The dishwashing task's economics: w_h 18 USD/h, MP_h 60/h, p 0.30, c_d 1.0, pi_e 0.12,
# capex 35,000 over 20,000 h, maintenance 0.9 USD/h, supervision 2.0 USD/h.
ECON = TaskEconomics(
    wage_human_usd_per_hour=18.0, mp_human_units_per_hour=60.0, value_per_unit_usd=0.30,
    damage_cost_usd_per_error=1.0, energy_price_usd_per_kwh=0.12, robot_capex_usd=35_000.0,
    robot_lifetime_h=20_000.0, maintenance_usd_per_hour=0.9, supervision_usd_per_hour=2.0,
)


def test_worked_example_competitive_robot():
    # MP_r 50/h, e_r 0.04, E_r 0.1 kWh/h, share 0.5:
    #   cost/h   = 35000/20000 + 0.9 + 2.0 + 0.12*0.1 = 1.75 + 2.9 + 0.012 = 4.662
    #   operating= 2.912;  unit cost = 4.662/50 = 0.09324;  human unit cost = 18/60 = 0.30
    #   spread   = 0.30 - 0.09324 = 0.20676;  price = 0.09324 + 0.5*0.20676 = 0.19662 USD/unit
    #   price/h  = 0.19662*50 = 9.831;  saving/h = (0.30 - 0.19662)*50 = 5.169
    #   break-even = 35000 / (9.831 - 2.912) = 35000/6.919 = 5058.53 h
    #   wage = 0.30*50 - 1.0*0.04*50 = 13.0 -> parity 13/18 = 0.7222;  EP = 50/0.1 = 500 units/kWh
    p = price_task(ECON, 50.0, 0.04, 0.1, PricingPolicy(0.5))
    assert p.robot_cost_usd_per_hour == pytest.approx(4.662)
    assert p.robot_operating_cost_usd_per_hour == pytest.approx(2.912)
    assert p.robot_unit_cost_usd == pytest.approx(0.09324)
    assert p.human_unit_cost_usd == pytest.approx(0.30)
    assert p.spread_per_unit_usd == pytest.approx(0.20676)
    assert p.price_usd_per_unit == pytest.approx(0.19662)
    assert p.price_usd_per_robot_hour == pytest.approx(9.831)
    assert p.customer_saving_usd_per_hour == pytest.approx(5.169)
    assert p.break_even_hours == pytest.approx(35000 / 6.919)
    assert p.implied_wage_usd_per_hour == pytest.approx(13.0)
    assert p.wage_parity == pytest.approx(13.0 / 18.0)
    assert p.energy_productivity_units_per_kwh == pytest.approx(500.0)
    assert p.competitive is True


def test_damage_is_priced_beside_the_unit_cost():
    # worked example above, e_h 0.05 (default), c_d 1.0: damage/unit = 1.0*0.04 = 0.04 (human 0.05);
    #   saving after damage = (0.30 + 0.05 - 0.19662 - 0.04) * 50 = 0.11338*50 = 5.669 USD/h
    p = price_task(ECON, 50.0, 0.04, 0.1, PricingPolicy(0.5))
    assert p.damage_usd_per_unit == pytest.approx(0.04)
    assert p.customer_saving_after_damage_usd_per_hour == pytest.approx(5.669)
    # a robot that falls a third of the time with 5 USD per error: cheap per unit, dear after damage
    #   unit cost 4.662/800 = 0.0058275; price = 0.0058275 + 0.5*(0.30 - 0.0058275) = 0.15291375
    #   damage/unit 5*0.33 = 1.65 (human 5*0.05 = 0.25); saving after damage = (0.55 - 1.80291375)*800
    costly = TaskEconomics(**{**ECON.__dict__, "damage_cost_usd_per_error": 5.0})
    q = price_task(costly, 800.0, 0.33, 0.1, PricingPolicy(0.5))
    assert q.competitive and q.customer_saving_usd_per_hour > 0
    assert q.damage_usd_per_unit == pytest.approx(1.65)
    assert q.customer_saving_after_damage_usd_per_hour == pytest.approx((0.55 - 1.80291375) * 800)


@pytest.mark.parametrize("share, price", [(0.0, 0.09324), (1.0, 0.30), (0.25, 0.09324 + 0.25 * 0.20676)])
def test_spread_share_moves_the_price_between_cost_and_the_human_unit_cost(share, price):
    p = price_task(ECON, 50.0, 0.04, 0.1, PricingPolicy(share))
    assert p.price_usd_per_unit == pytest.approx(price)
    assert p.customer_saving_usd_per_hour == pytest.approx((0.30 - price) * 50.0)


def test_uncompetitive_robot_is_priced_at_cost_and_costs_the_customer():
    # MP_r 10/h: unit cost 4.662/10 = 0.4662 > 0.30 -> spread -0.1662, price = cost,
    # saving (0.30 - 0.4662)*10 = -1.662/h; margin 4.662 - 2.912 = 1.75 = capex/h -> 20,000 h
    p = price_task(ECON, 10.0, 0.0, 0.1)
    assert not p.competitive
    assert p.spread_per_unit_usd == pytest.approx(-0.1662)
    assert p.price_usd_per_unit == pytest.approx(0.4662)
    assert p.customer_saving_usd_per_hour == pytest.approx(-1.662)
    assert p.break_even_hours == pytest.approx(ECON.robot_lifetime_h)


def test_robot_that_completes_nothing_has_infinite_price_and_no_break_even():
    p = price_task(ECON, 0.0, 0.0, 0.2)
    assert math.isinf(p.robot_unit_cost_usd) and math.isinf(p.price_usd_per_unit)
    assert math.isinf(p.break_even_hours) and p.customer_saving_usd_per_hour == 0.0
    assert p.wage_parity == 0.0 and not p.competitive


def test_invalid_inputs_are_config_errors():
    with pytest.raises(ConfigError, match="spread_share"):
        PricingPolicy(1.5)
    with pytest.raises(ConfigError, match="mpl_units_per_hour"):
        price_task(ECON, math.nan, 0.0, 0.1)
    with pytest.raises(ConfigError, match="energy_kwh_per_hour"):
        price_task(ECON, 10.0, 0.0, -1.0)


def test_quantiles_match_numpy_and_keep_infinity():
    import numpy as np

    values = [3.0, 1.0, 4.0, 1.5, 9.0, 2.6]
    for q in (0.1, 0.5, 0.9):
        assert quantile(values, q) == pytest.approx(np.percentile(values, q * 100))
    assert quantile([1.0, math.inf, math.inf], 0.9) == math.inf
    assert quantile([1.0, 2.0, math.inf], 0.5) == 2.0
    d = distribution([1.0, 2.0, 3.0, 4.0])
    assert d == {"mean": 2.5, "n": 4.0, "p10": pytest.approx(1.3), "p50": 2.5, "p90": pytest.approx(3.7)}


def test_price_evaluation_prices_the_pool_and_each_episode():
    # Two 30-minute episodes: 30 and 20 good units, 0 and 2 errors, 50 and 100 Wh.
    # Pool: 50 units / 1 h = 50/h, e = 2/52, E = 0.15 kWh/h. Episodes: 60/h and 40/h.
    meter = EconomicMeter(ECON)
    eps = [meter.summarize({"units_completed": 30, "errors": 0, "episode_length_s": 1800, "energy_wh": 50}),
           meter.summarize({"units_completed": 20, "errors": 2, "episode_length_s": 1800, "energy_wh": 100})]
    pool = meter.summarize({"units_completed": 50, "errors": 2, "episode_length_s": 3600, "energy_wh": 150})
    summary = price_evaluation(ECON, pool, eps, PricingPolicy(0.5))
    assert summary.aggregate.mpl_units_per_hour == pytest.approx(50.0)
    assert summary.aggregate.error_rate == pytest.approx(2 / 52)
    # pooled unit cost (1.75 + 2.9 + 0.12*0.15)/50 = 4.668/50 = 0.09336
    assert summary.aggregate.robot_unit_cost_usd == pytest.approx(0.09336)
    unit_costs = [(4.65 + 0.12 * 0.1) / 60, (4.65 + 0.12 * 0.2) / 40]
    d = summary.distributions["robot_unit_cost_usd"]
    assert d["mean"] == pytest.approx(sum(unit_costs) / 2)
    assert d["p50"] == pytest.approx(sum(unit_costs) / 2)
    assert d["p10"] == pytest.approx(unit_costs[0] + 0.1 * (unit_costs[1] - unit_costs[0]))
    assert summary.distributions["mpl_units_per_hour"]["p90"] == pytest.approx(58.0)
    doc = summary.to_dict()
    assert doc["spread_share"] == 0.5 and doc["units"]["break_even_hours"] == "h"


def test_pricing_inputs_list_every_number_with_unit_and_source():
    p = price_task(ECON, 50.0, 0.04, 0.1)
    rows = pricing_inputs(ECON, PricingPolicy(0.4), p, "measured: eval run 3, 5 episodes")
    names = [r["name"] for r in rows]
    assert {"wage_human_usd_per_hour", "robot_capex_usd", "spread_share", "robot_mpl_units_per_hour"} <= set(names)
    assert all(r["unit"] and r["source"] for r in rows)
    assert next(r for r in rows if r["name"] == "robot_error_rate")["source"].startswith("measured")


# A robot at no capital cost whose hour costs 4 USD (maintenance 1, supervision 3, no energy) next to
# a human at 20 USD/h doing 10 units/h (2 USD/unit): at 2 units/h its unit cost is exactly the human's.
EVEN = TaskEconomics(wage_human_usd_per_hour=20.0, mp_human_units_per_hour=10.0, value_per_unit_usd=1.0,
                     energy_price_usd_per_kwh=0.0, robot_capex_usd=0.0, maintenance_usd_per_hour=1.0,
                     supervision_usd_per_hour=3.0)


def test_a_robot_exactly_as_dear_as_a_human_is_not_competitive_and_without_capex_breaks_even_at_once():
    # unit cost 4/2 = 2.0 = human's 20/10: spread 0 -> not competitive, price = cost = 2.0 USD/unit,
    # price/h 4.0 = operating cost 4.0: margin 0, but there is no capex to repay -> 0 h
    p = price_task(EVEN, 2.0, 0.0, 0.0, PricingPolicy(0.5))
    assert p.spread_per_unit_usd == 0.0 and p.competitive is False
    assert p.price_usd_per_unit == 2.0 and p.price_usd_per_robot_hour == 4.0
    assert p.break_even_hours == 0.0
    # one unit/h more: unit cost 4/3, spread 2/3 > 0 -> competitive
    assert price_task(EVEN, 3.0, 0.0, 0.0).competitive is True


def test_a_margin_under_one_dollar_an_hour_still_repays_the_capex():
    # capex 10,000 over 20,000 h = 0.5 USD/h; uncompetitive at 10 units/h (unit cost (0.5 + 2.9)/10 = 0.34
    # > 0.30), so priced at cost: the margin over operating cost is the 0.5 USD/h of capex -> 20,000 h
    cheap = TaskEconomics(**{**ECON.__dict__, "robot_capex_usd": 10_000.0, "energy_price_usd_per_kwh": 0.0})
    p = price_task(cheap, 10.0, 0.0, 0.0)
    assert not p.competitive and p.price_usd_per_unit == pytest.approx(0.34)
    assert p.break_even_hours == pytest.approx(20_000.0)


def test_a_robot_that_completes_nothing_charges_nothing_it_can_quote_per_hour():
    # no unit: the price per unit and per hour are infinite, and the customer saves nothing, damage or not
    p = price_task(ECON, 0.0, 0.5, 0.2)
    assert p.price_usd_per_robot_hour == math.inf
    assert p.customer_saving_usd_per_hour == 0.0 and p.customer_saving_after_damage_usd_per_hour == 0.0
    # a robot so slow that its unit cost overflows to inf still works: it costs the customer without bound
    slow = price_task(ECON, 1e-310, 0.0, 0.2)
    assert slow.price_usd_per_unit == math.inf
    assert slow.customer_saving_usd_per_hour == -math.inf


@pytest.mark.parametrize("name, args, bad", [("mpl_units_per_hour", (-1.0, 0.0, 0.1), "-1.0"),
                                             ("error_rate", (10.0, math.inf, 0.1), "inf"),
                                             ("energy_kwh_per_hour", (10.0, 0.0, math.nan), "nan")])
def test_a_bad_robot_metric_names_itself(name, args, bad):
    with pytest.raises(ConfigError) as info:
        price_task(ECON, *args)
    assert info.value.key == name
    assert str(info.value) == f"<robot metrics>: key '{name}': must be finite and >= 0, got {bad}"


@pytest.mark.parametrize("share", [1.5, -0.1, math.nan, True, "0.5", None])
def test_a_spread_share_outside_0_1_or_not_a_number_is_refused_with_what_is_allowed(share):
    with pytest.raises(ConfigError) as info:
        PricingPolicy(share)
    assert str(info.value) == (f"<pricing>: key 'spread_share': must be a number in [0, 1], got {share!r} "
                               "(allowed: 0 <= s <= 1)")


def test_price_from_metrics_uses_the_policy_and_names_a_missing_key():
    metrics = {"mpl_units_per_hour": 50.0, "error_rate": 0.04, "energy_kwh_per_hour": 0.1}
    assert price_from_metrics(ECON, metrics, PricingPolicy(0.0)).price_usd_per_unit == pytest.approx(0.09324)
    with pytest.raises(ConfigError) as info:
        price_from_metrics(ECON, {"mpl_units_per_hour": 50.0, "error_rate": 0.04})
    assert info.value.key == "energy_kwh_per_hour"
    assert str(info.value) == ("<econ metrics>: key 'energy_kwh_per_hour': missing; expected "
                               "EconomicMeter.summarize keys")


def test_quantile_between_a_finite_and_an_infinite_value_is_the_infinite_one():
    assert quantile([1.0, math.inf], 0.5) == math.inf
    assert quantile([-math.inf, 1.0], 0.5) == -math.inf
    assert quantile([-math.inf, 1.0], 1.0) == 1.0
    empty = distribution([])
    assert empty["n"] == 0.0 and all(math.isnan(empty[k]) for k in ("mean", "p10", "p50", "p90"))


def test_price_evaluation_applies_the_policy_to_the_pool_and_every_episode():
    # share 0: every price is the robot's unit cost (worked example: 4.662/50 for the pool)
    meter = EconomicMeter(ECON)
    ep = meter.summarize({"units_completed": 25, "episode_length_s": 1800, "energy_wh": 50})
    pool = meter.summarize({"units_completed": 50, "episode_length_s": 3600, "energy_wh": 100})
    summary = price_evaluation(ECON, pool, [ep, ep], PricingPolicy(0.0))
    assert summary.aggregate.price_usd_per_unit == pytest.approx(0.09324)
    assert [p.price_usd_per_unit for p in summary.episodes] == pytest.approx([0.09324, 0.09324])
    doc = summary.to_dict()
    assert doc["aggregate"]["price_usd_per_unit"] == pytest.approx(0.09324)
    assert doc["distributions"]["price_usd_per_unit"]["n"] == 2.0
    # no episode: the pool is priced, and there is no distribution to give
    alone = price_evaluation(ECON, pool, [])
    assert alone.episodes == () and alone.distributions == {}


def test_pricing_inputs_rows_give_the_value_unit_and_source_of_the_policy_and_the_measurements():
    p = price_task(ECON, 50.0, 0.04, 0.1)
    rows = {r["name"]: r for r in pricing_inputs(ECON, PricingPolicy(0.4), p, "eval run 3")}
    assert rows["spread_share"] == {"name": "spread_share", "value": 0.4, "unit": "fraction of spread",
                                    "source": "pricing policy (--spread-share)"}
    assert rows["robot_mpl_units_per_hour"] == {"name": "robot_mpl_units_per_hour", "value": 50.0,
                                                "unit": "units/h", "source": "eval run 3"}
    assert rows["robot_error_rate"]["value"] == 0.04 and rows["robot_energy_kwh_per_hour"]["value"] == 0.1
