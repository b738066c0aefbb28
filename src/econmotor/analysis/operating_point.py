"""Operating points and choices: what each recorded run delivers, with intervals, and how far each objective's
choice stands above its runner-up.

A walker swept over commanded speeds (``econmotor sweep --policy ... --command-speed 0.4,0.6``) is one run per
speed, so the run ``econmotor solve`` picks for an objective is that objective's speed. For the episodes of a
run, pooled as a report pools them (ratios of sums)::

    MPL               = sum units_completed / sum hours                     units/h
    Wh per unit       = sum energy_wh / sum units_completed                 Wh/unit
    units per charge  = C / Wh per unit                                     units (C = battery_capacity_wh, Wh)
    error rate        = sum errors / sum units_attempted                    errors/attempted unit
    price per unit    = price_task(MPL, error rate, sum energy_wh / 1000 / sum hours)    USD/unit
    damage per unit   = damage_cost_usd_per_error * error rate              USD/unit (the buyer's, on top)

(``economics/battery.py``, ``economics/pricing.py``; units per charge only for a task with a battery; the
price at the default pricing policy, half the spread to the seller), each with the report's interval
(:func:`econmotor.economics.uncertainty.assess`: exact Clopper-Pearson bounds on the error rate, a seeded
bootstrap over the run's episodes for the rest; Wh per unit from the same resamples; damage per unit at the
error rate's bounds), each end one-sided at :data:`~econmotor.economics.uncertainty.CONFIDENCE` (a 90%
interval).

The choice of an objective under a constraint set is the solver's best valid run ``b``
(:mod:`econmotor.analysis.objective_surface`). Its mean J gets a bootstrap interval over ``b``'s episodes;
the margin ``J_b - J_n`` over the runner-up ``n`` (the valid run of next highest mean J) one from
independent resamples of both runs' episodes (episodes of different runs are not paired). A margin whose
lower end is above 0 says the episodes separate the choice from its runner-up; one that reaches 0 says
they do not.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from econmotor.analysis.episode_table import COUNT_COLUMNS, EpisodeTable
from econmotor.analysis.objective_surface import ObjectiveSurface, reward_term_matrix
from econmotor.config.task_economics import TaskEconomics
from econmotor.economics import labour
from econmotor.economics.pricing import price_task
from econmotor.economics.uncertainty import (
    BOOTSTRAP_RESAMPLES,
    BOOTSTRAP_SEED,
    CONFIDENCE,
    Evidence,
    Interval,
    assess,
)
from econmotor.errors import UnknownNameError

#: the figures of an operating point, with their units (units per charge only for a task with a battery)
OPERATING_FIGURES: dict[str, str] = {
    "mpl_units_per_hour": "units/h",
    "energy_wh_per_unit": "Wh/unit",
    "battery_units_per_charge": "units/charge",
    "error_rate": "errors/attempted unit",
    "price_usd_per_unit": "USD/unit",
    "damage_usd_per_unit": "USD/unit",
}


@dataclass(frozen=True)
class OperatingPoint:
    """One run's pooled figures (module docstring), each a 90% :class:`Interval`, and their evidence."""

    run_id: str
    commanded_speed_m_per_s: float | None
    evidence: Evidence
    figures: Mapping[str, Interval]

    def to_dict(self) -> dict[str, Any]:
        return {"run_id": self.run_id, "commanded_speed_m_per_s": self.commanded_speed_m_per_s,
                "evidence": self.evidence.to_dict(), "figures": {k: v.to_dict() for k, v in self.figures.items()}}


def task_economics(task_ids: Sequence[str], task_files: Sequence[str] = ()) -> dict[str, TaskEconomics]:
    """Task id -> its economics from the task catalog (tasks the catalog does not know are left out)."""
    from econmotor.tasks import load_catalog

    catalog = load_catalog(task_files)
    out: dict[str, TaskEconomics] = {}
    for task_id in task_ids:
        try:
            out[task_id] = catalog.get(task_id).economics
        except UnknownNameError:
            continue
    return out


def run_rows(table: EpisodeTable, r: int) -> np.ndarray:
    """Run ``r``'s episodes as rows ``[hours, units_completed, units_attempted, errors, energy_wh]``."""
    start = int(table.run_starts[r])
    stop = start + int(table.episode_counts()[r])
    names = (*(table.counts[n] for n in COUNT_COLUMNS), table.columns["energy_wh"])
    return np.column_stack([column[start:stop] for column in names])


def _wh_per_unit(rows: np.ndarray) -> Interval:
    """Pooled Wh per unit and its bootstrap interval, on the resamples :func:`assess` draws (same seed)."""
    n = len(rows)
    picks = np.random.default_rng(BOOTSTRAP_SEED).integers(0, n, size=(BOOTSTRAP_RESAMPLES, n))
    units, wh = rows[:, 1][picks].sum(axis=1), rows[:, 4][picks].sum(axis=1)
    values = np.divide(wh, units, out=np.full(len(units), np.inf), where=units > 0)
    total_units, total_wh = rows[:, 1].sum(), rows[:, 4].sum()
    point = float(total_wh / total_units) if total_units > 0 else math.inf
    low, high = (float(np.quantile(values, q, method="inverted_cdf")) for q in (1.0 - CONFIDENCE, CONFIDENCE))
    return Interval(point, min(low, point), max(high, point),
                    f"bootstrap over {n} episodes, {BOOTSTRAP_RESAMPLES} resamples, seed {BOOTSTRAP_SEED}")


def operating_point(table: EpisodeTable, r: int, economics: TaskEconomics) -> OperatingPoint | None:
    """Run ``r``'s operating point under ``economics``; None where its episodes lack the counts."""
    rows = run_rows(table, r)
    if not np.all(np.isfinite(rows)):
        return None
    hours, units, attempted, errors, wh = rows.sum(axis=0)
    point = price_task(economics, labour.mpl_units_per_hour(units, hours), labour.error_rate(errors, attempted),
                       wh / 1000.0 / hours if hours > 0 else 0.0)
    episodes = [dict(zip(("hours", "units_completed", "units_attempted", "errors", "energy_wh"), row, strict=True))
                for row in rows.tolist()]
    uncertainty = assess(economics, episodes, point)
    figures = {name: uncertainty.intervals[name] for name in OPERATING_FIGURES if name in uncertainty.intervals}
    figures["energy_wh_per_unit"] = _wh_per_unit(rows)
    rate, cost = uncertainty.intervals["error_rate"], economics.damage_cost_usd_per_error
    figures["damage_usd_per_unit"] = Interval(point.damage_usd_per_unit, cost * rate.low, cost * rate.high,
                                              f"damage_cost_usd_per_error x the error rate's bounds ({rate.method})")
    run = table.runs[r]
    return OperatingPoint(run.run_id, run.commanded_speed_m_per_s, uncertainty.evidence,
                          {name: figures[name] for name in OPERATING_FIGURES if name in figures})


def operating_points(table: EpisodeTable, economics: Mapping[str, TaskEconomics]) -> list[OperatingPoint]:
    """The operating point of every run whose task has economics here and whose episodes carry the counts,
    in table order (see :func:`task_economics`)."""
    out = []
    for r, run in enumerate(table.runs):
        if run.task_id in economics:
            found = operating_point(table, r, economics[run.task_id])
            if found is not None:
                out.append(found)
    return out


@dataclass(frozen=True)
class Choice:
    """An objective's best valid run under a constraint set, its mean J and its margin over the runner-up."""

    objective: str
    constraint_set: str
    run_id: str
    commanded_speed_m_per_s: float | None
    utility: Interval
    runner_up_run_id: str | None
    margin: Interval | None

    @property
    def separated(self) -> bool:
        """The margin's lower end is above 0: the episodes tell the choice from its runner-up."""
        return self.margin is not None and self.margin.low > 0

    def to_dict(self) -> dict[str, Any]:
        return {"objective": self.objective, "constraint_set": self.constraint_set, "run_id": self.run_id,
                "commanded_speed_m_per_s": self.commanded_speed_m_per_s, "utility": self.utility.to_dict(),
                "runner_up_run_id": self.runner_up_run_id,
                "margin": None if self.margin is None else self.margin.to_dict(), "separated": self.separated}


def _resampled_means(values: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    picks = rng.integers(0, len(values), size=(BOOTSTRAP_RESAMPLES, len(values)))
    return values[picks].mean(axis=1)


def _interval(point: float, samples: np.ndarray, what: str) -> Interval:
    low, high = (float(np.quantile(samples, q, method="inverted_cdf")) for q in (1.0 - CONFIDENCE, CONFIDENCE))
    return Interval(point, min(low, point), max(high, point),
                    f"bootstrap of {what}, {BOOTSTRAP_RESAMPLES} resamples, seed {BOOTSTRAP_SEED}")


def _choice(surface: ObjectiveSurface, k: int, c: int, j: np.ndarray) -> Choice:
    """The choice of objective ``k`` under set ``c`` (a set some run meets); ``j``: every episode's J under k."""
    table, best = surface.table, int(surface.best_run[k, c])
    others = np.where(surface.valid[:, c] & (np.arange(table.num_runs) != best), surface.utility[:, k], -np.inf)
    runner = int(np.argmax(others)) if np.isfinite(others).any() else None
    by_run = np.split(j, table.run_starts[1:])
    rng = np.random.default_rng(BOOTSTRAP_SEED)
    best_means = _resampled_means(by_run[best], rng)
    utility = _interval(float(surface.utility[best, k]), best_means, f"the mean J over {len(by_run[best])} episodes")
    margin = None
    if runner is not None:
        diff = best_means - _resampled_means(by_run[runner], rng)
        margin = _interval(float(surface.utility[best, k] - surface.utility[runner, k]), diff,
                           "the difference of two runs' mean J (independent resamples)")
    run = table.runs[best]
    return Choice(surface.objectives[k].name, surface.constraint_sets[c].name, run.run_id,
                  run.commanded_speed_m_per_s, utility, None if runner is None else table.runs[runner].run_id, margin)


def choices(surface: ObjectiveSurface) -> list[Choice]:
    """The choice of every named objective (presets and vectors; grid vectors are left out) under every
    constraint set some run meets, objectives outermost."""
    terms = {}
    out = []
    for k, objective in enumerate(surface.objectives):
        if objective.kind == "grid":
            continue
        if objective.energy_term not in terms:
            terms[objective.energy_term] = reward_term_matrix(surface.table, objective.energy_term)
        j = terms[objective.energy_term] @ np.asarray(objective.weights, dtype=np.float64)
        out += [_choice(surface, k, c, j) for c in range(len(surface.constraint_sets)) if surface.best_run[k, c] >= 0]
    return out
