"""How far the evaluation episodes let us trust a price: intervals, evidence and the deployability verdict.

Every headline figure of a report is a point estimate from a handful of episodes; this
module says how uncertain it is and whether the robot may be priced at all.

- **Error rate**: the exact (Clopper-Pearson) binomial bounds on ``errors`` in
  ``attempted`` units. Each end is a one-sided bound at ``confidence`` (95%), so the two
  together form a ``2*confidence - 1`` (90%) interval::

      upper = Beta.ppf(confidence, k + 1, n - k)      (1 when k = n)
      lower = Beta.ppf(1 - confidence, k, n - k + 1)  (0 when k = 0)

  Worked example: 0 errors in 9 attempts -> upper = 1 - 0.05**(1/9) = 0.2831.
  Fractional counts (legs counted fractionally) use the same Beta quantiles.
- **MPL, implied wage, unit cost, spread, price**: a seeded bootstrap over episodes
  (``resamples`` resamples of the episodes with replacement; each resample is pooled the
  way the aggregate is, ratios of sums, and priced by
  :func:`econmotor.economics.pricing.price_task`); the interval is the
  ``1 - confidence`` and ``confidence`` quantiles of the resampled values.
- **The conservative price**: :func:`price_task` on the unfavourable end of every
  measured input, MPL at its lower bound, error rate and energy per hour at their upper
  bounds. It covers the robot's cost unless it performs worse than every bound.
- **The verdict** (:func:`decide`): deployable when the robot completed work, the error
  rate's upper bound is within the task's acceptance limit (``max_error_rate``, the
  human's rate unless the catalog says otherwise) and the MPL lower bound reaches the
  task's ``min_units_per_hour``. Otherwise the reasons say why, in words.
- **Evidence sized to the verdict**: a sequential evaluation judges its episodes after every batch
  (:mod:`econmotor.economics.sequential_rule`); the error rate's bounds are then a confidence
  sequence (:func:`error_rate_sequence`, valid at ``confidence`` at every look at once).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
from scipy.special import betaincinv, betaln  # (scipy.stats and .optimize take a second to import)

from econmotor.config.acceptance import ERROR_RATE_CHECK, Acceptance
from econmotor.config.task_economics import TaskEconomics
from econmotor.economics import labour
from econmotor.economics.pricing import PricingPolicy, TaskPrice, price_task

#: one-sided confidence of every bound (each end of a 90% interval).
CONFIDENCE = 0.95
#: bootstrap resamples and seed (fixed: the same episodes always give the same interval).
BOOTSTRAP_RESAMPLES = 2000
BOOTSTRAP_SEED = 20240601
#: TaskPrice fields given a bootstrap interval, with the end that is unfavourable to the buyer's case.
BOOTSTRAP_FIELDS: dict[str, str] = {
    "mpl_units_per_hour": "low",
    "energy_kwh_per_hour": "high",
    "implied_wage_usd_per_hour": "low",
    "wage_parity": "low",
    "robot_unit_cost_usd": "high",
    "spread_per_unit_usd": "low",
    "price_usd_per_unit": "high",
    "price_usd_per_robot_hour": "high",
}
#: The battery's figures (a task whose robot has one), with the end unfavourable to the buyer.
BATTERY_BOOTSTRAP_FIELDS: dict[str, str] = {
    "battery_runtime_h": "low",
    "battery_units_per_charge": "low",
    "battery_charging_share": "high",
    "mpl_units_per_paid_hour": "low",
}


def clopper_pearson(errors: float, attempted: float, confidence: float = CONFIDENCE) -> tuple[float, float]:
    """(lower, upper) exact binomial bounds on a rate, each one-sided at ``confidence``.

    With nothing attempted the rate is unknown: ``(0.0, 1.0)``.
    """
    k, n = float(errors), float(attempted)
    if n <= 0:
        return 0.0, 1.0
    k = min(max(k, 0.0), n)
    lower = 0.0 if k <= 0 else float(betaincinv(k, n - k + 1.0, 1.0 - confidence))  # Beta(k, n-k+1) quantile
    upper = 1.0 if k >= n else float(betaincinv(k + 1.0, n - k, confidence))
    return lower, upper


#: the error-rate confidence sequence's mixing distribution: this weight on "never errs", the rest on
#: Beta(1, b) with its mean at a quarter of the rate tested (the acceptance limit). Fall-free units to
#: bound a 0.05 (0.01) limit at 95%: 64 (324), exact fixed-n bound 59 (299), Bonferroni over 7 looks
#: 97 (492); with 1 error 140 (710) vs 93 (477) and 138 (702) (the choice among w 0.5/0.8, mean at
#: 1, 1/4, 1/10 of the limit that needs the fewest units over 0-2 errors).
SEQUENCE_ZERO_WEIGHT = 0.5
SEQUENCE_MEAN_SHARE = 0.25
ERROR_SEQUENCE_METHOD = ("confidence sequence (beta-binomial mixture martingale with Ville's inequality: "
                         "valid at every look at once)")


def _mixture_log_ratio_level(k: float, n: float, w: float, b: float, alpha: float) -> float:
    """``log(1/alpha) - log(mixture likelihood)`` for the mixture ``w delta_0 + (1 - w) Beta(1, b)``: a rate
    ``p`` is outside the sequence where ``-log L(p) = -(k log p + (n-k) log(1-p))`` exceeds it."""
    log_mix = math.log1p(-w) + betaln(1.0 + k, b + n - k) - betaln(1.0, b) if w < 1.0 else -math.inf
    if k == 0 and w > 0.0:
        log_mix = float(np.logaddexp(math.log(w), log_mix))
    return math.log(1.0 / alpha) - log_mix


def error_rate_sequence(errors: float, attempted: float, confidence: float = CONFIDENCE,
                        rate: float = 0.05) -> tuple[float, float]:
    """(lower, upper) bounds on an error rate, each one-sided at ``confidence`` simultaneously over every
    number of units: a sequential evaluation may stop whenever they decide (anytime-valid).

    Each end is the edge of the set of rates ``p`` whose mixture likelihood ratio
    ``M(p) = [w 1{k=0} + (1-w) B(1+k, b+n-k) / B(1, b)] / (p^k (1-p)^(n-k))`` stays below
    ``1 / (1 - confidence)`` (a nonnegative martingale under ``p``; Ville's inequality bounds the chance
    it ever crosses; Howard et al. 2021, "Time-uniform, nonparametric, nonasymptotic confidence
    sequences"). The upper end's mixture is for a rate inside ``rate`` (the limit the sequence tests):
    ``w`` = :data:`SEQUENCE_ZERO_WEIGHT` and ``b = 1 / (SEQUENCE_MEAN_SHARE rate) - 1``; the lower end's
    for a rate above it: ``w = 0``, the Beta's mean at ``rate / SEQUENCE_MEAN_SHARE`` (at most 1/2). With
    0 errors the upper end is closed-form, ``1 - (alpha (w + (1 - w) b / (n + b)))**(1/n)``; worked example,
    0 errors in 100 units at 95%, rate 0.05 (b = 79): ``1 - (0.05 (0.5 + 0.5 * 79/179))**0.01 = 0.0327``.
    Nothing attempted: ``(0, 1)``.
    """
    from scipy.optimize import brentq  # here, not at the top: every CLI command imports this module

    k, n = float(errors), float(attempted)
    if n <= 0:
        return 0.0, 1.0
    k = min(max(k, 0.0), n)
    alpha, rate = 1.0 - confidence, min(max(rate, 1e-6), 1.0)
    mle = k / n

    def outside(level: float) -> Callable[[float], float]:  # -log L(p) - level: below 0 inside the sequence
        return lambda p: -(k * math.log(p) if k > 0 else 0.0) - ((n - k) * math.log1p(-p) if n > k else 0.0) - level

    level = _mixture_log_ratio_level(k, n, SEQUENCE_ZERO_WEIGHT, 1.0 / (SEQUENCE_MEAN_SHARE * rate) - 1.0, alpha)
    if k <= 0:
        upper = -math.expm1(-level / n)  # (1-p)^n = exp(-level)
    elif k >= n or outside(level)(1.0 - 1e-15) <= 0:  # (almost) every unit an error: no rate below 1 excluded
        upper = 1.0
    else:
        upper = brentq(outside(level), mle, 1.0 - 1e-15, xtol=1e-12)
    lower = 0.0
    if k > 0:
        low_level = _mixture_log_ratio_level(k, n, 0.0, 1.0 / min(rate / SEQUENCE_MEAN_SHARE, 0.5) - 1.0, alpha)
        if outside(low_level)(1e-300) > 0:
            lower = brentq(outside(low_level), 1e-300, mle, xtol=1e-15)
    return float(lower), float(min(upper, 1.0))


@dataclass(frozen=True)
class Interval:
    """A point estimate with its bounds (each one-sided at the report's confidence)."""

    point: float
    low: float
    high: float
    method: str
    confidence: float | None = None  # of each bound, where it differs from the Uncertainty's

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


@dataclass(frozen=True)
class Evidence:
    """How much the figures rest on."""

    episodes: int
    units_attempted: float
    units_completed: float
    errors: float
    episodes_with_errors: int
    robot_hours: float

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


def _pooled(rows: np.ndarray) -> tuple[float, float, float]:
    """(MPL, error rate, kWh/h) of summed episode columns [hours, completed, attempted, errors, Wh]."""
    hours, units, attempted, errors, wh = rows
    return (labour.mpl_units_per_hour(units, hours), labour.error_rate(errors, attempted),
            wh / 1000.0 / hours if hours > 0 else 0.0)


def _columns(episodes: Sequence[Mapping[str, Any]]) -> np.ndarray:
    def num(ep: Mapping[str, Any], key: str, default: float = 0.0) -> float:
        value = ep.get(key)
        return float(value) if value is not None else default

    out = []
    for ep in episodes:
        units, errors = num(ep, "units_completed"), num(ep, "errors")
        attempted = num(ep, "units_attempted", units + errors)
        hours = num(ep, "hours", num(ep, "episode_length_s") / 3600.0)
        out.append((hours, units, attempted, errors, num(ep, "energy_wh")))
    return np.asarray(out, dtype=np.float64).reshape(len(out), 5)


@dataclass(frozen=True)
class Uncertainty:
    """Intervals on the headline figures, the evidence and the conservative price."""

    confidence: float
    evidence: Evidence
    intervals: dict[str, Interval]
    conservative: TaskPrice
    resamples: int
    seed: int

    def to_dict(self) -> dict[str, Any]:
        return {"confidence": self.confidence, "interval_coverage": 2 * self.confidence - 1,
                "resamples": self.resamples, "seed": self.seed, "evidence": self.evidence.to_dict(),
                "intervals": {k: v.to_dict() for k, v in self.intervals.items()},
                "conservative": self.conservative.to_dict()}


def assess(economics: TaskEconomics, episodes: Sequence[Mapping[str, Any]], point: TaskPrice,
           policy: PricingPolicy = PricingPolicy(), confidence: float = CONFIDENCE,
           resamples: int = BOOTSTRAP_RESAMPLES, seed: int = BOOTSTRAP_SEED,
           sequence_rate: float | None = None, sequence_confidence: float = CONFIDENCE) -> Uncertainty:
    """Intervals for ``point`` (the pooled price of ``episodes``) from the episodes themselves.

    ``sequence_rate``: a sequential evaluation's look; the error rate's bounds are then its confidence
    sequence (:func:`error_rate_sequence` at ``sequence_confidence``, the plan's confidence, tuned to test
    ``sequence_rate``), the others at ``confidence``."""
    cols = _columns(episodes)
    total = cols.sum(axis=0)
    evidence = Evidence(episodes=len(episodes), units_attempted=float(total[2]), units_completed=float(total[1]),
                        errors=float(total[3]), episodes_with_errors=int((cols[:, 3] > 0).sum()),
                        robot_hours=float(total[0]))
    lo_q, hi_q = 1.0 - confidence, confidence
    intervals: dict[str, Interval] = {}
    if sequence_rate is None:
        err_lo, err_hi = clopper_pearson(total[3], total[2], confidence)
        intervals["error_rate"] = Interval(point.error_rate, err_lo, err_hi, "Clopper-Pearson exact binomial")
    else:
        err_lo, err_hi = error_rate_sequence(total[3], total[2], sequence_confidence, sequence_rate)
        intervals["error_rate"] = Interval(point.error_rate, err_lo, err_hi, ERROR_SEQUENCE_METHOD,
                                           sequence_confidence)
    boot_fields = {**BOOTSTRAP_FIELDS, **(BATTERY_BOOTSTRAP_FIELDS if point.has_battery else {})}
    samples: dict[str, np.ndarray] = {name: np.zeros(0) for name in boot_fields}
    if len(episodes):
        rng = np.random.default_rng(seed)
        picks = rng.integers(0, len(episodes), size=(resamples, len(episodes)))
        # each resample's summed columns, 256 resamples at a time (a few MB however many episodes)
        pools = np.concatenate([cols[chunk].sum(axis=1) for chunk in np.split(picks, range(256, resamples, 256))])
        # each distinct pool is priced once: episodes that repeat (whole units, one energy figure)
        # give a few distinct pools among the resamples, and the prices are the same
        distinct, which = np.unique(pools, axis=0, return_inverse=True)
        prices = [price_task(economics, *_pooled(pool), policy) for pool in distinct]
        for name in boot_fields:
            samples[name] = np.asarray([getattr(p, name) for p in prices], dtype=np.float64)[which.reshape(-1)]
    method = f"bootstrap over {len(episodes)} episodes, {resamples} resamples, seed {seed}"
    for name in boot_fields:
        values = samples[name]
        value = getattr(point, name)
        if values.size == 0:
            intervals[name] = Interval(value, math.nan, math.nan, method)
            continue
        # 'inverted_cdf' keeps inf (a resample that completed nothing) instead of nan
        low, high = (float(np.quantile(values, q, method="inverted_cdf")) for q in (lo_q, hi_q))
        intervals[name] = Interval(value, min(low, value), max(high, value), method)
    mpl_lo = intervals["mpl_units_per_hour"].low
    kwh_hi = intervals["energy_kwh_per_hour"].high
    conservative = price_task(economics, max(mpl_lo, 0.0) if math.isfinite(mpl_lo) else 0.0, err_hi,
                              kwh_hi if math.isfinite(kwh_hi) else point.energy_kwh_per_hour, policy)
    return Uncertainty(confidence, evidence, intervals, conservative, resamples, seed)


@dataclass(frozen=True)
class Verdict:
    """Deployable or not, and why (``reasons`` is empty when deployable)."""

    deployable: bool
    reasons: tuple[str, ...]
    checks: tuple[dict[str, Any], ...]
    acceptance: Acceptance

    @property
    def label(self) -> str:
        return "deployable" if self.deployable else "not deployable"

    def to_dict(self) -> dict[str, Any]:
        return {"deployable": self.deployable, "label": self.label, "reasons": list(self.reasons),
                "checks": list(self.checks), "acceptance": self.acceptance.to_dict()}


def number_text(value: float) -> str:
    """A figure in a sentence: thousands separators from 1000 on, else 3 significant digits."""
    return f"{value:,.0f}" if abs(value) >= 1000 else f"{value:.3g}"


def percent(confidence: float) -> str:
    """A confidence in words: ``0.95 -> '95%'``, ``0.991667 -> '99.2%'``."""
    return f"{confidence * 100:.3g}%"


def _plural(name: str, count: float) -> str:
    return name if count == 1 else (name[:-1] + "ies" if name.endswith("y") else name + "s")


def counted(count: int, name: str) -> str:
    """``count`` and ``name`` in the plural it takes: "1 run", "2 runs", "35 more objectives"."""
    return f"{count} {_plural(name, count)}"


def judge(economics: TaskEconomics, acceptance: Acceptance, unit: str, episodes: Sequence[Mapping[str, Any]],
          point: TaskPrice, policy: PricingPolicy = PricingPolicy(),
          confidence: float = CONFIDENCE, sequential: bool = False,
          sequence_confidence: float = CONFIDENCE) -> tuple[Uncertainty, Verdict]:
    """The intervals of evaluation episodes (:func:`assess`) and the verdict on them (:func:`decide`):
    the one judgement a report prints and evaluation-driven training selects checkpoints by.
    ``confidence``: of each bound; ``sequential``: a sequential evaluation's look (judged at its plan's
    ``look_confidence``, the error rate by its confidence sequence at ``sequence_confidence``: the plan's
    ``confidence``, :class:`~econmotor.economics.sequential_rule.SequentialPlan`)."""
    uncertainty = assess(economics, episodes, point, policy, confidence,
                         sequence_rate=acceptance.max_error_rate if sequential else None,
                         sequence_confidence=sequence_confidence)
    return uncertainty, decide(acceptance, uncertainty, economics.error_rate_human, unit)


def decide(acceptance: Acceptance, uncertainty: Uncertainty, human_error_rate: float, unit: str) -> Verdict:
    """Apply the acceptance rule to the evaluation (module docstring)."""
    ev, iv = uncertainty.evidence, uncertainty.intervals
    pct = percent(uncertainty.confidence)
    err, mpl = iv["error_rate"], iv["mpl_units_per_hour"]
    name = acceptance.error_name
    reasons: list[str] = []
    checks: list[dict[str, Any]] = []

    worked = ev.units_completed > 0
    checks.append({"name": "completes work", "measured": ev.units_completed, "limit": 0.0, "passed": worked,
                   "text": f"{number_text(ev.units_completed)} units ({unit}) completed in {ev.episodes} "
                           "episodes"})
    if not worked:
        reasons.append(f"completed no unit ({unit}) in {ev.episodes} evaluation episodes")

    err_pct = percent(err.confidence) if err.confidence is not None else pct
    err_ok = err.high <= acceptance.max_error_rate
    in_episodes = (f"in {ev.episodes_with_errors} of {ev.episodes} episodes" if ev.episodes_with_errors
                   else f"in none of {ev.episodes} episodes")
    text = (f"{_plural(name, 2)} {in_episodes} ({number_text(ev.errors)} in {number_text(ev.units_attempted)} "
            f"attempted); {err_pct} upper bound on the {name} rate {number_text(err.high)} vs "
            f"{number_text(acceptance.max_error_rate)} accepted ({number_text(human_error_rate)} for a human)")
    checks.append({"name": ERROR_RATE_CHECK, "measured": err.point, "bound": err.high,
                   "limit": acceptance.max_error_rate, "passed": err_ok, "text": text})
    if not err_ok and worked:
        reasons.append(text)

    mpl_ok = worked and mpl.low >= acceptance.min_units_per_hour
    text = (f"{pct} lower bound on throughput {number_text(mpl.low)} units/h vs at least "
            f"{number_text(acceptance.min_units_per_hour)} required")
    checks.append({"name": "throughput", "measured": mpl.point, "bound": mpl.low,
                   "limit": acceptance.min_units_per_hour, "passed": mpl_ok, "text": text})
    if worked and not mpl_ok:
        reasons.append(text)
    return Verdict(not reasons, tuple(reasons), tuple(checks), acceptance)
