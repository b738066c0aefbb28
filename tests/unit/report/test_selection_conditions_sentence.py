"""A run's report says under which conditions its policy was chosen (the run record's ``selection_conditions``:
held-out episode i under ``conditions[i % len]``, seeded ``first + i``), and only where a held-out evaluation ran."""

from __future__ import annotations

from typing import Any

from econmotor.economics.pricing import PricingPolicy, price_evaluation
from econmotor.motor_backend.results import summarize_episodes
from econmotor.motor_backend.selection import Selection, SelectionConfig
from econmotor.objectives import EconomicObjectiveSpec
from econmotor.report.document import ReportContext, build_document
from econmotor.report.render import render_markdown
from econmotor.report.text import selection_text
from econmotor.store.records import RunRecord
from econmotor.tasks import get_task

#: one-hour shifts: 60 dishes, no error
SHIFTS = [{"units_completed": 60, "errors": 0, "episode_length_s": 3600, "energy_wh": 100.0} for _ in range(32)]


def _document(backend_config: dict[str, Any]) -> dict[str, Any]:
    task = get_task("dishwashing")
    train = RunRecord(id=4, kind="train", task_id="dishwashing", backend="mujoco", status="completed",
                      objective_name="obj", objective={}, datapack_ids=(), config={"backend_config": backend_config},
                      seed=3, num_envs=16, max_steps=32000, policy_path="runs/g1", raw_metrics={}, econ_metrics={},
                      training_curve=[], artifacts={}, notes="", error=None, parent_run_id=None, robot_id=None,
                      created_at=None, finished_at=None)
    raw, econ, episodes = summarize_episodes(SHIFTS[:3], task.economics)
    return build_document(ReportContext(
        task=task, backend="mujoco", objective=EconomicObjectiveSpec(name="obj"), datapack_ids=(),
        pricing=price_evaluation(task.economics, econ, episodes, PricingPolicy(0.5)), raw_metrics=raw,
        econ_metrics=econ, episodes=episodes, training_curve=[], notes="", db_url="sqlite:///x", train_run=train))


def _selection(evaluated: bool) -> dict[str, Any]:
    selection = Selection(get_task("dishwashing"), EconomicObjectiveSpec(name="obj"),
                          SelectionConfig(every_steps=1, episodes=32, seed=3, batch=16))
    if evaluated:
        selection.consider(1_000, lambda n, first, stop: SHIFTS[:n])
    return selection.record()


def test_the_report_says_the_conditions_the_policy_was_chosen_under() -> None:
    doc = _document({"selection": _selection(True), "selection_conditions": ["nominal", "humanoid_stress"]})
    assert doc["selection"]["conditions"] == ["nominal", "humanoid_stress"] and doc["selection"]["look_episodes"] == 16
    sentence = ("Chosen by held-out evaluations of at most 32 episodes, judged every 16, alternating nominal and "
                "humanoid_stress conditions episode by episode (seeds 50003-50034)")
    assert selection_text(doc["selection"]).endswith(sentence)
    assert sentence in render_markdown(doc, {})
    nominal = _document({"selection": _selection(True), "selection_conditions": ["nominal"]})
    assert "judged every 16, under nominal conditions (seeds 50003-50034)" in selection_text(nominal["selection"])


def test_no_sentence_without_recorded_conditions_or_without_a_held_out_evaluation() -> None:
    assert "Chosen by" not in selection_text(_document({"selection": _selection(True)})["selection"])
    unjudged = _document({"selection": _selection(False), "selection_conditions": ["nominal"]})
    assert "Chosen by" not in selection_text(unjudged["selection"])  # the last weights were kept unjudged
