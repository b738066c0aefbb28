"""A sequential evaluation (motor_backend/sequential.py) bounds the error rate by its confidence sequence at its
plan's confidence, not at the module's 95%: a plan at 90% says so, and decides on the evidence 90% needs."""

from __future__ import annotations

import pytest

from econmotor.economics.sequential_rule import SequentialPlan
from econmotor.economics.uncertainty import error_rate_sequence
from econmotor.motor_backend.sequential import SequentialEvaluation
from econmotor.tasks import get_task

TASK = get_task("hopper_courier")  # fall rate upper bound <= 0.05, >= 100 legs/h


def episode(legs: float, fell: bool = False) -> dict:
    """One 8 s courier episode's raw metrics (a fall ends it and counts as an attempted leg)."""
    return {"units_completed": legs, "units_attempted": legs + (1.0 if fell else 0.0), "errors": 1.0 if fell else 0.0,
            "episode_length_s": 8.0, "energy_wh": 0.05, "risk_score": 0.0, "novelty_score": 0.0,
            "return": 100.0 * legs, "length_steps": 1000.0, "termination_reason": "fall" if fell else "max_steps"}


SAFE = [episode(1.2) for _ in range(64)]  # no fall, 1.2 legs per episode


@pytest.mark.parametrize("confidence", [0.9, 0.95, 0.99])
def test_a_look_bounds_the_error_rate_at_the_plans_confidence(confidence: float) -> None:
    run = SequentialEvaluation(TASK, SequentialPlan(batch=16, max_episodes=64, confidence=confidence))
    run.stop([*SAFE[:15], episode(0.4, fell=True)])  # 1 fall in 19.4 attempted legs (18 + 0.4 + 1)
    err = run.judged.uncertainty.intervals["error_rate"]
    assert err.confidence == confidence
    assert (err.low, err.high) == pytest.approx(error_rate_sequence(1.0, 19.4, confidence, 0.05))
    assert f"{confidence * 100:.3g}% upper bound on the fall rate" in run.judged.verdict.checks[1]["text"]
    assert run.judged.uncertainty.confidence == run.plan.look_confidence  # the bootstrap bounds: alpha-spending


def test_a_plan_at_90_percent_passes_on_the_evidence_90_percent_needs() -> None:
    # 0 falls: 57.6 legs (48 episodes) bound the rate at 0.043 at 90%, 0.055 at 95%; 76.8 legs (64) at 0.042 at 95%
    at_90 = SequentialEvaluation(TASK, SequentialPlan(batch=16, max_episodes=64, confidence=0.9))
    at_95 = SequentialEvaluation(TASK, SequentialPlan(batch=16, max_episodes=64, confidence=0.95))
    assert len(at_90.finish(SAFE)) == 48 and at_90.passed
    assert len(at_95.finish(SAFE)) == 64 and at_95.passed
