"""Evidence sized to the verdict: the sequential rule that says when an evaluation has run enough episodes.

A sequential evaluation runs episodes in batches and judges them after every batch (the looks, up
to a cap: :class:`SequentialPlan`) until the acceptance rule is decided (:func:`look_outcome`):

- **pass**: every bound inside its limit (the verdict of :func:`econmotor.economics.uncertainty.decide`);
- **fail**: a bound's favourable end outside its limit (:func:`certainly_fails`): the error rate's
  lower bound above ``max_error_rate``, or throughput's upper bound below ``min_units_per_hour``;
- **continue**: neither yet; the evaluation stops anyway at the episode or wall-time cap.

The bounds stay valid however early it stops (:data:`SEQUENTIAL_METHOD`): the error rate's are a
confidence sequence (:func:`econmotor.economics.uncertainty.error_rate_sequence`, valid at
``confidence`` at every look at once), the bootstrap ones are at ``1 - (1 - confidence) / K`` for K
looks (alpha-spending, Bonferroni; with ``confidence`` 0.95 and K = 5 looks, each look's bootstrap
bounds are at 99%). A policy whose true rate equals the limit is judged deployable at most
``1 - confidence`` of the time (tests/unit/economics/test_sequential.py).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from econmotor.config.acceptance import Acceptance
from econmotor.economics.uncertainty import CONFIDENCE, Uncertainty, Verdict, number_text, percent
from econmotor.errors import ConfigError

#: the anytime-valid method of a sequential evaluation, as the report and docs/architecture.md name it.
SEQUENTIAL_METHOD = ("a look after every batch; the error rate's bounds a confidence sequence (beta-binomial "
                     "mixture, Ville's inequality: valid at every look at once), the bootstrap bounds alpha-spending "
                     "over the looks (Bonferroni: each of the K looks at (1 - confidence) / K); each bound is wrong at "
                     "most 1 - confidence of the time, whenever the evaluation stops")
#: a sequential evaluation's defaults where the user gives no cap: episodes and wall seconds.
DEFAULT_MAX_EPISODES = 640
DEFAULT_MAX_WALL_S = 900.0


@dataclass(frozen=True)
class SequentialPlan:
    """How a sequential evaluation looks at its episodes (the schedule is fixed before any episode runs).

    Looks come after every batch: ``batch``, ``2 batch``, ``3 batch``, ... episodes and at
    ``max_episodes`` (the cap); each look judges the first ``n_k`` episodes (in seed order). The error
    rate's bounds are its confidence sequence
    (:func:`~econmotor.economics.uncertainty.error_rate_sequence`), valid at ``confidence`` at every
    look at once; each bootstrap bound is at :attr:`look_confidence` = ``1 - (1 - confidence) / K``:
    one wrong at some look is wrong at one of the K looks, so by the union bound the chance that it is
    wrong at any look is at most ``1 - confidence``. Stopping at the first look that decides keeps
    every bound valid (:data:`SEQUENTIAL_METHOD`). A wall-time cap only removes looks.

    Attributes:
        batch: episodes of the first look (the backend's evaluation batch).
        max_episodes: the cap on episodes (the last look).
        max_wall_s: the cap on wall seconds (checked at each look that did not decide).
        confidence: the one-sided confidence of every bound over all looks together.
    """

    batch: int
    max_episodes: int = DEFAULT_MAX_EPISODES
    max_wall_s: float = DEFAULT_MAX_WALL_S
    confidence: float = CONFIDENCE

    def __post_init__(self) -> None:
        if self.batch < 1:
            raise ConfigError("<sequential evaluation>", "batch", f"must be >= 1, got {self.batch}")
        if self.max_episodes < self.batch:
            raise ConfigError("--eval-max-episodes", None, f"{self.max_episodes} is below one evaluation batch "
                              f"({self.batch} episodes)", f"{self.batch} or more")
        if not (self.max_wall_s > 0 and math.isfinite(self.max_wall_s)):
            raise ConfigError("--eval-max-seconds", None, f"must be a positive number of seconds, "
                              f"got {self.max_wall_s}")

    @property
    def looks(self) -> tuple[int, ...]:
        """Episode counts at which the evaluation is judged: every ``batch`` below the cap, then the cap."""
        return (*range(self.batch, self.max_episodes, self.batch), self.max_episodes)

    @property
    def look_confidence(self) -> float:
        """The confidence of each look's bootstrap bounds: ``1 - (1 - confidence) / len(looks)``."""
        return 1.0 - (1.0 - self.confidence) / len(self.looks)

    def to_dict(self) -> dict[str, Any]:
        return {"batch": self.batch, "max_episodes": self.max_episodes, "max_wall_s": self.max_wall_s,
                "confidence": self.confidence, "looks": list(self.looks), "look_confidence": self.look_confidence,
                "method": SEQUENTIAL_METHOD}


#: a look's outcomes: every bound inside its limit / a bound certainly outside / not decided yet.
PASS, FAIL, CONTINUE = "pass", "fail", "continue"


def certainly_fails(acceptance: Acceptance, uncertainty: Uncertainty) -> str | None:
    """Why the acceptance rule certainly fails (a bound's favourable end is outside its limit), or None:
    the error rate's lower bound above ``max_error_rate``, or throughput's upper bound below
    ``min_units_per_hour``."""
    err, mpl = uncertainty.intervals["error_rate"], uncertainty.intervals["mpl_units_per_hour"]
    pct, name = percent(uncertainty.confidence), acceptance.error_name
    if err.low > acceptance.max_error_rate:
        err_pct = percent(err.confidence) if err.confidence is not None else pct
        return (f"the {name} rate is above {number_text(acceptance.max_error_rate)} ({err_pct} lower bound "
                f"{number_text(err.low)})")
    if acceptance.min_units_per_hour > 0 and math.isfinite(mpl.high) and mpl.high < acceptance.min_units_per_hour:
        return (f"throughput is below {number_text(acceptance.min_units_per_hour)} units/h ({pct} upper bound "
                f"{number_text(mpl.high)})")
    return None


def look_outcome(acceptance: Acceptance, uncertainty: Uncertainty, verdict: Verdict) -> tuple[str, str]:
    """``(PASS | FAIL | CONTINUE, why)`` of one look judged at its confidence."""
    if verdict.deployable:
        return PASS, "every bound inside its limit"
    why = certainly_fails(acceptance, uncertainty)
    return (FAIL, why) if why else (CONTINUE, "; ".join(verdict.reasons))
