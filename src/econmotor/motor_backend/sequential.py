"""Sequential evaluation: run episodes in batches until the task's acceptance rule is decided.

The rule and its looks are :class:`econmotor.economics.sequential_rule.SequentialPlan` (a look after every
batch; the error rate's confidence sequence and alpha-spending for the other bounds keep them valid under
this optional stopping). This module drives a
backend's evaluation with it: a backend's ``evaluate_policy(..., stop=...)`` (or a held-out
evaluation's ``evaluate(n, first_seed, stop)``) calls ``stop(rows)`` with the episodes finished so
far, in seed order, whenever a batch has ended; :meth:`SequentialEvaluation.stop` judges every look
those rows reach and answers True once the evaluation is decided:

- **pass**: every bound inside its limit (the error rate's confidence sequence, the others at the look's
  confidence);
- **fail**: a bound certainly outside its limit (:func:`~econmotor.economics.sequential_rule.certainly_fails`),
  or the rule cannot pass by the cap even if every episode still to run matched the best one so far
  (fall-free first, then the most units): early checkpoints that fall in most episodes cost one batch;
- **episode cap** / **time cap**: the last look, or a look after ``max_wall_s``, did not decide.

The episodes judged are the first ``n`` of the deciding look; episodes a backend finished beyond it are
dropped. :meth:`SequentialEvaluation.record` is what a run records under ``sequential``.
"""

from __future__ import annotations

import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from econmotor.economics.pricing import PricingSummary, price_evaluation
from econmotor.economics.sequential_rule import CONTINUE, FAIL, PASS, SEQUENTIAL_METHOD, SequentialPlan, look_outcome
from econmotor.economics.uncertainty import CONFIDENCE, Uncertainty, Verdict, judge
from econmotor.motor_backend.results import MotorEvalResult, evaluation_result, summarize_episodes

#: how an evaluation ended, beyond pass and fail.
EPISODE_CAP, TIME_CAP = "episode cap", "time cap"


@dataclass(frozen=True)
class Judged:
    """Raw episodes judged as the report judges them: per-episode summaries, pricing, intervals, verdict."""

    summaries: list[dict[str, Any]]
    pricing: PricingSummary
    uncertainty: Uncertainty
    verdict: Verdict


def judge_raw(task: Any, raw_episodes: Sequence[Mapping[str, Any]], confidence: float = CONFIDENCE,
              sequential: bool = False, sequence_confidence: float = CONFIDENCE) -> Judged:
    """The report's judgement (:func:`econmotor.economics.uncertainty.judge`) of raw-metric episodes
    (``base.py``'s keys) under ``task``'s economics and acceptance rule, every bound at ``confidence``
    (``sequential``: a look of a sequential evaluation, the error rate by its confidence sequence at
    ``sequence_confidence``, the plan's confidence)."""
    economics = task.economics
    _, econ, summaries = summarize_episodes(raw_episodes, economics)
    pricing = price_evaluation(economics, econ, summaries)
    uncertainty, verdict = judge(economics, task.acceptance, task.unit, summaries, pricing.aggregate,
                                 pricing.policy, confidence, sequential, sequence_confidence)
    return Judged(summaries, pricing, uncertainty, verdict)


@dataclass
class SequentialEvaluation:
    """One sequential evaluation under ``plan`` of ``task`` (a catalog TaskSpec); see the module docstring."""

    task: Any
    plan: SequentialPlan
    started: float = field(default_factory=time.perf_counter)
    looks: list[dict[str, Any]] = field(default_factory=list)
    outcome: str | None = None
    why: str = ""
    decided_at: int = 0
    judged: Judged | None = None

    def _look(self, rows: Sequence[Mapping[str, Any]], n: int) -> str:
        judged = self._judge(rows[:n])
        outcome, why = look_outcome(self.task.acceptance, judged.uncertainty, judged.verdict)
        if outcome == CONTINUE and n < self.plan.max_episodes and self.hopeless(rows[:n]):
            outcome, why = FAIL, (f"cannot pass within {self.plan.max_episodes} episodes even if every episode "
                                  "left matched the best so far")
        elapsed = time.perf_counter() - self.started
        if outcome == CONTINUE and n >= self.plan.max_episodes:
            outcome, why = EPISODE_CAP, f"undecided at the cap of {self.plan.max_episodes} episodes"
        elif outcome == CONTINUE and elapsed >= self.plan.max_wall_s:
            outcome, why = TIME_CAP, (f"undecided after {elapsed:.0f} s (cap {self.plan.max_wall_s:g} s, "
                                      "--eval-max-seconds)")
        self.looks.append({"episodes": n, "outcome": outcome, "why": why, "wall_s": round(elapsed, 3)})
        self.judged = judged
        if outcome != CONTINUE:
            self.outcome, self.why, self.decided_at = outcome, why, n
        return outcome

    def hopeless(self, rows: Sequence[Mapping[str, Any]]) -> bool:
        """True when the rule cannot pass at the cap even if every episode still to run matched the best
        one so far (fall-free first, then the most units), judged at the look confidence."""
        rows = list(rows)
        left = self.plan.max_episodes - len(rows)
        if left <= 0 or not rows:
            return False
        best = max(rows, key=lambda r: (float(r.get("errors", 0.0)) == 0.0, float(r.get("units_completed", 0.0))))
        return not self._judge(rows + [best] * left).verdict.deployable

    def _judge(self, rows: Sequence[Mapping[str, Any]]) -> Judged:
        """A look's judgement: the bootstrap bounds at the plan's look confidence, the error rate by its
        confidence sequence at the plan's confidence."""
        return judge_raw(self.task, rows, self.plan.look_confidence, sequential=True,
                         sequence_confidence=self.plan.confidence)

    def stop(self, rows: Sequence[Mapping[str, Any]]) -> bool:
        """Judge every look the first ``len(rows)`` episodes reach; True once decided (a backend's ``stop``)."""
        done = self.looks[-1]["episodes"] if self.looks else 0
        for n in self.plan.looks:
            if self.outcome is not None:
                break
            if done < n <= len(rows):
                self._look(rows, n)
        return self.outcome is not None

    def finish(self, rows: Sequence[Mapping[str, Any]]) -> list[Mapping[str, Any]]:
        """The episodes the verdict rests on: judges the looks ``rows`` reach that were not judged yet
        (a backend stops calling ``stop`` at its last batch), then the first ``decided_at`` episodes
        (without a decision, those of the last look)."""
        self.stop(rows)
        if self.outcome is None:  # fewer episodes than the next look (a backend ran out): the last look stands
            self.decided_at = self.looks[-1]["episodes"] if self.looks else 0
            self.outcome, self.why = EPISODE_CAP, f"stopped after {len(rows)} episodes, before the next look"
        return list(rows[:self.decided_at])

    @property
    def passed(self) -> bool:
        return self.outcome == PASS

    def record(self) -> dict[str, Any]:
        """What a run records under ``sequential``: the plan, every look, the outcome and what it cost."""
        return {"method": SEQUENTIAL_METHOD, "plan": self.plan.to_dict(), "confidence": self.plan.look_confidence,
                "looks": list(self.looks), "outcome": self.outcome, "why": self.why, "episodes": self.decided_at,
                "wall_s": round(time.perf_counter() - self.started, 3)}


def evaluate_sequentially(backend: Any, policy_id: str, task: Any, objective: Any, plan: SequentialPlan, seed: int,
                          **kwargs: Any) -> MotorEvalResult:
    """``backend.evaluate_policy`` of up to ``plan.max_episodes`` episodes (episode i seeded ``seed + i``),
    stopped once the acceptance rule is decided; the result holds the episodes the verdict rests on and
    ``config["sequential"]`` (:meth:`SequentialEvaluation.record`)."""
    run = SequentialEvaluation(task, plan)
    result = backend.evaluate_policy(policy_id, task.task_id, objective, plan.max_episodes, seed, stop=run.stop,
                                     **kwargs)
    rows = run.finish(result.episodes)
    config = {**result.config, "num_episodes": len(rows), "sequential": run.record()}
    out = kwargs.get("output_dir")
    return evaluation_result(result.backend, policy_id, task.task_id, rows, task.economics, config,
                             Path(out) if out is not None and (Path(out) / "evaluation.json").exists() else None)
