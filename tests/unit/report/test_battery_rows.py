"""The pricing table shows a battery's figures where the other econ metrics are, only for a robot that has one."""

from __future__ import annotations

import dataclasses
import json

import pytest

from econmotor.economics.pricing import PricingPolicy, price_evaluation
from econmotor.motor_backend.results import summarize_episodes
from econmotor.objectives import EconomicObjectiveSpec
from econmotor.report.document import ReportContext, build_document
from econmotor.report.render import render_markdown
from econmotor.report.text import BATTERY_ROWS, PRICE_ROWS, fmt, table_rows
from econmotor.tasks import get_task

# ten one-hour shifts of 60 dishes on 100 Wh (E_r 0.1 kWh/h, 1/0.6 Wh per dish)
SHIFTS = [{"units_completed": 60, "errors": 0, "episode_length_s": 3600, "energy_wh": 100.0} for _ in range(10)]


def _doc(battery: bool) -> dict:
    task = get_task("dishwashing")
    if battery:  # 400 Wh, 1 h recharge: 4 h per charge, 240 dishes per charge, a fifth of the paid hours charging
        task = dataclasses.replace(task, economics=dataclasses.replace(
            task.economics, battery_capacity_wh=400.0, battery_recharge_h=1.0,
            sources={**task.economics.sources, "battery_capacity_wh": "test", "battery_recharge_h": "test"}))
    raw, econ, episodes = summarize_episodes(SHIFTS, task.economics)
    pricing = price_evaluation(task.economics, econ, episodes, PricingPolicy(0.5))
    ctx = ReportContext(task=task, backend="dishwashing", objective=EconomicObjectiveSpec(name="obj"),
                        datapack_ids=(), pricing=pricing, raw_metrics=raw, econ_metrics=econ, episodes=episodes)
    return build_document(ctx)


def test_a_battery_robot_report_shows_units_per_charge_runtime_and_hours_lost():
    doc = _doc(battery=True)
    json.dumps(doc, allow_nan=False)
    agg = doc["pricing"]["aggregate"]
    assert agg["battery_runtime_h"] == pytest.approx(4.0)
    assert agg["battery_units_per_charge"] == pytest.approx(240.0)
    assert agg["battery_charging_share"] == pytest.approx(0.2)
    assert agg["mpl_units_per_paid_hour"] == pytest.approx(48.0)
    # robot unit cost per paid hour: (4.65 + 0.12*0.08) / 48
    assert agg["robot_unit_cost_usd"] == pytest.approx((4.65 + 0.12 * 0.08) / 48)
    assert doc["metrics"]["econ"]["battery_units_per_charge"] == pytest.approx(240.0)
    rows = {r[0]: r for r in table_rows(doc)}
    labels = [r[0] for r in table_rows(doc)]
    for key, label in BATTERY_ROWS:
        assert rows[label][1] == fmt(agg[key]) and rows[label][-1] == doc["pricing"]["units"][key]
    assert rows[BATTERY_ROWS[1][1]][1] == "240" and rows[BATTERY_ROWS[1][1]][-1] == "units/charge"
    assert rows[BATTERY_ROWS[2][1]][2]  # an interval
    # after the energy rows, before the wage and the costs
    assert labels.index(BATTERY_ROWS[0][1]) == labels.index("energy productivity") + 1
    assert "units per charge (battery capacity / energy per unit) | 240 |" in render_markdown(doc)
    assert any(r["name"] == "battery_capacity_wh" and r["unit"] == "Wh" for r in doc["inputs"])


def test_a_robot_without_a_battery_has_no_battery_rows():
    doc = _doc(battery=False)
    assert [r[0] for r in table_rows(doc)] == [label for _, label in PRICE_ROWS]
    assert not any(key in doc["pricing"]["aggregate"] or key in doc["pricing"]["units"] for key, _ in BATTERY_ROWS)
    assert "per charge" not in render_markdown(doc)


def test_the_runtime_row_says_the_makers_runtime_where_the_evaluation_records_one():
    from econmotor.motor_backend.results import PROVENANCE_KEY

    doc = _doc(battery=True)
    runtime_label = BATTERY_ROWS[0][1]
    assert runtime_label in [r[0] for r in table_rows(doc)]  # no evaluation provenance: the plain label
    doc["runs"] = {**(doc.get("runs") or {}), "eval": {"config": {PROVENANCE_KEY: {
        "stated_runtime_h": 2.0, "stated_runtime": "continuous operation", "stated_runtime_source": "spec sheet"}}}}
    rows = {r[0]: r for r in table_rows(doc)}
    label = ("runtime per charge (battery capacity / robot energy per hour; the maker states 2 h of continuous "
             "operation)")
    assert label in rows and rows[label][1] == "4"  # the meter's figure beside the maker's (console, md, html)
