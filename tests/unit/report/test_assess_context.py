"""A report of a sequential evaluation judges its verdict as the evaluation's looks did: the error rate by its
confidence sequence at the plan's confidence (recorded with the run), the other bounds at the look confidence."""

from __future__ import annotations

from types import SimpleNamespace

from econmotor.economics.pricing import PricingPolicy, price_evaluation
from econmotor.economics.sequential_rule import SequentialPlan
from econmotor.motor_backend.results import summarize_episodes
from econmotor.motor_backend.sequential import SequentialEvaluation
from econmotor.objectives import EconomicObjectiveSpec
from econmotor.report.document import ReportContext, assess_context
from econmotor.tasks import get_task

TASK = get_task("hopper_courier")
RAW = [{"units_completed": 1.2, "units_attempted": 1.2, "errors": 0.0, "episode_length_s": 8.0, "energy_wh": 0.05,
        "termination_reason": "max_steps"} for _ in range(64)]


def test_a_sequential_evaluation_at_90_percent_is_judged_at_90_percent() -> None:
    run = SequentialEvaluation(TASK, SequentialPlan(batch=16, max_episodes=64, confidence=0.9))
    rows = run.finish(RAW)
    raw_metrics, econ, episodes = summarize_episodes(rows, TASK.economics)
    priced = SimpleNamespace(id=2, kind="eval", config={"backend_config": {"sequential": run.record()}})
    ctx = ReportContext(task=TASK, backend="mujoco", objective=EconomicObjectiveSpec(), datapack_ids=(),
                        pricing=price_evaluation(TASK.economics, econ, episodes, PricingPolicy()),
                        raw_metrics=raw_metrics, econ_metrics=econ, episodes=episodes, eval_run=priced)
    uncertainty, verdict = assess_context(ctx)
    assert verdict.deployable and verdict.checks[1]["text"].startswith(
        "falls in none of 48 episodes (0 in 57.6 attempted); 90% upper bound on the fall rate 0.0431")
    assert verdict.checks[1]["bound"] == run.judged.verdict.checks[1]["bound"]  # the deciding look's own bound
    assert uncertainty.confidence == 0.95  # the table's intervals stay at the report's confidence
