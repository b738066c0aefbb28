"""The report shows each priced episode's J (the one ``episode_j``) and datapack hints as written."""

from __future__ import annotations

from types import SimpleNamespace

import pytest

from econmotor.config.datapacks import parse_datapack
from econmotor.config.objective_profile import ObjectiveVector
from econmotor.economics.pricing import PricingPolicy, price_evaluation
from econmotor.motor_backend.results import summarize_episodes
from econmotor.objectives import objective_from_vector
from econmotor.report.document import ReportContext, build_document
from econmotor.report.render import render_markdown
from econmotor.tasks import get_task
from econmotor.valuation import episode_j

HINT = "prioritise throughput on fragile items"


def test_report_carries_episode_j_and_free_text_hints():
    task = get_task("dishwashing")  # priced at 0.12 USD/kWh: J still counts energy in Wh
    raw = [{"units_completed": 60, "units_attempted": 64, "errors": 4, "episode_length_s": 3600.0, "energy_wh": 12.0,
            "termination_reason": "max_steps"},
           {"units_completed": 30, "units_attempted": 40, "errors": 10, "episode_length_s": 3600.0,
            "energy_wh": 30.0, "termination_reason": "catastrophic_error"}]
    raw_metrics, econ, episodes = summarize_episodes(raw, task.economics)
    objective = objective_from_vector(ObjectiveVector.from_preset("energy_saver"), "energy_saver")
    packs = [parse_datapack({"id": "upstream", "objective_hint": HINT}), parse_datapack({"id": "plain"})]
    run = SimpleNamespace(id=7, kind="train", status="completed", seed=0, num_envs=1, max_steps=10, policy_path="p",
                          parent_run_id=None, objective_name="energy_saver", datapack_ids=("upstream", "plain"),
                          config={"datapacks": [p.to_dict() for p in packs]}, artifacts={}, created_at=None,
                          finished_at=None)
    ctx = ReportContext(task=task, backend="dishwashing", objective=objective, datapack_ids=("upstream", "plain"),
                        pricing=price_evaluation(task.economics, econ, episodes, PricingPolicy()),
                        raw_metrics=raw_metrics, econ_metrics=econ, episodes=episodes, train_run=run)
    doc = build_document(ctx)
    # by hand: energy_saver [1, 1, 3, 1, 0]; 60/h, 4/64 errors, 12 Wh; 30/h, 10/40 errors, 30 Wh, catastrophic
    hand = [60 - 4 / 64 - 3 * 12, 30 - 10 / 40 - 3 * 30 - 1]
    assert [ep["J"] for ep in doc["episodes"]] == pytest.approx(hand)
    assert [ep["J"] for ep in doc["episodes"]] == pytest.approx(
        [episode_j(ep, [1, 1, 3, 1, 0], task.economics) for ep in episodes])
    assert doc["objective"]["J"] == {"vector": [1, 1, 3, 1, 0], "energy_term": "wh",
                                     "mean": pytest.approx(sum(hand) / 2)}
    assert doc["datapack_objective_hints"] == {"upstream": HINT}
    markdown = render_markdown(doc)
    assert f"upstream (objective hint: {HINT})" in markdown and "plain" in markdown
    assert "objective J" in markdown


def test_the_reports_j_is_the_objectives_own_with_a_priced_energy_term():
    task = get_task("dishwashing")  # 0.12 USD/kWh
    raw = [{"units_completed": 60, "units_attempted": 64, "errors": 4, "episode_length_s": 3600.0, "energy_wh": 12.0,
            "termination_reason": "max_steps"}]
    raw_metrics, econ, episodes = summarize_episodes(raw, task.economics)
    objective = objective_from_vector(ObjectiveVector.from_preset("energy_saver", energy_term="usd"), "priced")
    ctx = ReportContext(task=task, backend="dishwashing", objective=objective, datapack_ids=(),
                        pricing=price_evaluation(task.economics, econ, episodes, PricingPolicy()),
                        raw_metrics=raw_metrics, econ_metrics=econ, episodes=episodes)
    doc = build_document(ctx)
    hand = 60 - 4 / 64 - 3 * (0.12 * 12.0 / 1000)  # energy_saver [1, 1, 3, 1, 0], 12 Wh at 0.12 USD/kWh
    assert doc["episodes"][0]["J"] == pytest.approx(hand)
    assert doc["objective"]["J"]["energy_term"] == "usd" and doc["objective"]["energy_term"] == "usd"
