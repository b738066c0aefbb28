"""The objective surface: re-score recorded episodes under many objectives and constraint sets.

For episodes ``i`` of runs ``r``, objectives ``k`` (weight vectors on
``[mpl, error, energy, safety, novelty]``) and constraint sets ``c``:

- reward terms (RewardBuilder, DESIGN.md §3), matrix ``T`` (N x 5), built by
  :func:`econmotor.valuation.reward_builder.reward_terms_from_metrics` (the formulas
  :func:`~econmotor.valuation.reward_builder.episode_j` uses, vectorised)::

      T[i] = [mpl_i, -error_rate_i, -Wh_i, -1 if catastrophic_i else 0, novelty_i]

  with ``-(pi_e_i * Wh_i / 1000)`` in place of ``-Wh_i`` only for objectives whose
  ``energy_term`` option is ``"usd"`` (the task's electricity price; an error where unknown).
- utility of a run under an objective: the mean episodic ``J = episode_j(episode, w_k)``
  ``= combine_reward(w_k, T[i])``.
  J is linear in T, so ``U = mean_r(T) @ W`` with ``W`` (5 x K): the per-run mean of T
  (``np.add.reduceat`` over run-sorted episodes) times the weight matrix. Identical to
  ``(T @ W)`` averaged per run, at R/N of the cost.
- validity of a run under a constraint set: the set's limits hold for the run's *mean*
  wage parity, error rate and energy (Wh per good unit or per episode, per the set's
  ``energy_basis``); ``valid_fraction`` is the share of the run's episodes that meet them.
- penalised utility (spec §5): ``U - 10 * sum(violations of the run means)``.
- best valid run per (objective, set): ``argmax_r U[r, k]`` over valid runs; ties go to the
  first run in table order. A set that no run meets is reported as such, together with
  the run of highest penalised utility (the least bad compromise).

No Python loop runs over episodes or runs; loops run over constraint sets only when
building their limit vectors.
"""

from __future__ import annotations

import itertools
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from econmotor.analysis.episode_table import EpisodeTable
from econmotor.config.objective_profile import OBJECTIVE_PRESETS, ObjectiveVector, check_energy_term
from econmotor.errors import ConfigError, UnknownNameError
from econmotor.valuation.constraints import PENALTY_SCALE, ConstraintSet, parse_constraint_set
from econmotor.valuation.reward_builder import REWARD_TERM_NAMES, reward_terms_from_metrics


@dataclass(frozen=True)
class Objective:
    """A named weight vector on ``[mpl, error, energy, safety, novelty]`` and its energy-term option."""

    name: str
    weights: tuple[float, float, float, float, float]
    kind: str = "vector"  # "preset" | "grid" | "vector"
    energy_term: str = "wh"  # "wh" (spec §7) or "usd" (priced), see econmotor.config.objective_profile

    def __post_init__(self) -> None:
        check_energy_term(self.energy_term, f"<objective {self.name}>")

    def to_dict(self) -> dict:
        return {"name": self.name, "weights": list(self.weights), "kind": self.kind, "energy_term": self.energy_term}

    @classmethod
    def from_vector(cls, vector: ObjectiveVector, name: str | None = None, kind: str = "vector") -> Objective:
        """An ObjectiveVector (weights and energy-term option) under a name."""
        label = name or "w[" + ",".join(f"{v:g}" for v in vector.to_list()) + "]"
        return cls(label, tuple(vector.to_list()), kind, vector.energy_term)


def preset_objectives(names: Sequence[str] | None = None) -> list[Objective]:
    """The six presets (or the named ones), in :data:`OBJECTIVE_PRESETS` order."""
    names = list(OBJECTIVE_PRESETS) if not names else list(names)
    for name in names:
        if name not in OBJECTIVE_PRESETS:
            raise UnknownNameError("objective preset", name, OBJECTIVE_PRESETS)
    return [Objective(n, tuple(ObjectiveVector.from_preset(n).to_list()), "preset") for n in names]


def simplex_grid(divisions: int, include_novelty: bool = False) -> list[Objective]:
    """Every weight vector with entries in ``{0, 1/m, ..., 1}`` summing to 1 (``m = divisions``).

    Over ``[mpl, error, energy, safety]`` (novelty weight 0) there are ``C(m+3, 3)`` vectors
    (m=4: 35, m=5: 56); with ``include_novelty`` over all five, ``C(m+4, 4)``.
    """
    if divisions < 1:
        raise ConfigError("<objectives>", "grid_divisions", f"must be >= 1, got {divisions}")
    dims = 5 if include_novelty else 4
    out = []
    for combo in itertools.product(range(divisions + 1), repeat=dims):
        if sum(combo) != divisions:
            continue
        w = [c / divisions for c in combo] + ([] if include_novelty else [0.0])
        label = "grid[" + ",".join(f"{x:g}" for x in w) + "]"
        out.append(Objective(label, tuple(w), "grid"))
    return out


def reward_term_matrix(table: EpisodeTable, energy_term: str = "wh") -> np.ndarray:
    """The RewardBuilder terms of every episode, (N, 5) in :data:`REWARD_TERM_NAMES` order.

    ``energy_term="usd"`` prices ``r_energy`` with each episode's electricity price.
    """
    cols = table.columns
    terms = reward_terms_from_metrics(cols["mpl_units_per_hour"], cols["error_rate"], cols["energy_wh"],
                                      table.catastrophic, cols["novelty_score"], energy_term=energy_term,
                                      energy_price_usd_per_kwh=table.energy_price_usd_per_kwh)
    return np.column_stack([np.broadcast_to(np.asarray(terms[name], dtype=np.float64), (table.num_episodes,))
                            for name in REWARD_TERM_NAMES])


@dataclass(frozen=True)
class ConstraintLimits:
    """Constraint sets as vectors (C,): NaN where a set leaves a quantity free."""

    min_wage_parity: np.ndarray
    max_error_rate: np.ndarray
    max_energy_wh: np.ndarray
    per_episode_energy: np.ndarray  # bool: the set limits Wh per episode, not per good unit

    @classmethod
    def from_sets(cls, sets: Sequence[ConstraintSet]) -> ConstraintLimits:
        def vec(name: str) -> np.ndarray:
            return np.array([np.nan if getattr(s, name) is None else getattr(s, name) for s in sets], float)
        return cls(vec("min_wage_parity"), vec("max_error_rate"), vec("max_energy_Wh"),
                   np.array([s.energy_basis == "per_episode" for s in sets], bool))

    def violations(self, parity: np.ndarray, error: np.ndarray, wh_unit: np.ndarray,
                   wh_episode: np.ndarray) -> np.ndarray:
        """Summed non-negative violations, (M, C) for M rows of metrics (0 where met)."""
        energy = np.where(self.per_episode_energy[None, :], wh_episode[:, None], wh_unit[:, None])
        terms = (np.maximum(0.0, self.min_wage_parity[None, :] - parity[:, None]),
                 np.maximum(0.0, error[:, None] - self.max_error_rate[None, :]),
                 np.maximum(0.0, energy - self.max_energy_wh[None, :]))
        with np.errstate(invalid="ignore"):  # inf - inf never happens: limits are finite
            return sum(np.nan_to_num(t, nan=0.0, posinf=np.inf) for t in terms)


@dataclass(frozen=True)
class ObjectiveSurface:
    """Everything the solver computed; R runs, K objectives, C constraint sets.

    Attributes:
        table: the episodes solved over.
        objectives, constraint_sets: the axes.
        run_metrics: name -> (R,) run means: mpl_units_per_hour, error_rate, energy_wh,
            energy_wh_per_unit, wage_parity, novelty_score, risk_score, catastrophic_rate.
        utility: (R, K) mean J.
        valid: (R, C) run means meet the set.
        valid_fraction: (R, C) share of the run's episodes meeting the set.
        violation: (R, C) summed violations of the run means.
        best_run: (K, C) index of the best valid run, -1 when no run meets the set.
        fallback_run: (K, C) index of the run with the highest penalised utility.
    """

    table: EpisodeTable
    objectives: tuple[Objective, ...]
    constraint_sets: tuple[ConstraintSet, ...]
    run_metrics: dict[str, np.ndarray]
    utility: np.ndarray
    valid: np.ndarray
    valid_fraction: np.ndarray
    violation: np.ndarray
    best_run: np.ndarray
    fallback_run: np.ndarray

    def best_utility(self) -> np.ndarray:
        """(K, C) utility of the best valid run; NaN where no run meets the set."""
        k = np.arange(len(self.objectives))[:, None]
        util = self.utility[np.maximum(self.best_run, 0), k]
        return np.where(self.best_run >= 0, util, np.nan)


def solve_objective_surface(table: EpisodeTable, objectives: Sequence[Objective],
                            constraint_sets: Sequence[ConstraintSet]) -> ObjectiveSurface:
    """Score every run under every objective and constraint set (formulas in the module doc)."""
    if not objectives:
        raise ConfigError("<objectives>", None, "give at least one objective (a preset or a grid)")
    sets = list(constraint_sets) or [ConstraintSet(name="unconstrained")]
    weights = np.array([o.weights for o in objectives], dtype=np.float64).T      # (5, K)
    if weights.shape[0] != len(REWARD_TERM_NAMES):
        raise ConfigError("<objectives>", None, "every objective needs 5 weights")
    cols = table.columns
    terms = reward_term_matrix(table)                                          # (N, 5)
    stacked = np.column_stack([terms, *(cols[n] for n in ("mpl_units_per_hour", "error_rate", "energy_wh",
                                        "energy_wh_per_unit", "wage_parity", "novelty_score", "risk_score"))])
    means = table.run_means(stacked)                                           # (R, 12)
    names = ("mpl_units_per_hour", "error_rate", "energy_wh", "energy_wh_per_unit", "wage_parity",
             "novelty_score", "risk_score")
    run_metrics = {n: means[:, 5 + j] for j, n in enumerate(names)}
    run_metrics["catastrophic_rate"] = -means[:, 3]
    utility = means[:, :5] @ weights                                           # (R, K)
    priced = np.array([o.energy_term == "usd" for o in objectives])
    if priced.any():  # the priced option: the same terms with r_energy in USD, for those objectives only
        priced_means = table.run_means(reward_term_matrix(table, "usd"))
        utility[:, priced] = priced_means @ weights[:, priced]

    limits = ConstraintLimits.from_sets(sets)
    violation = limits.violations(run_metrics["wage_parity"], run_metrics["error_rate"],
                                  run_metrics["energy_wh_per_unit"], run_metrics["energy_wh"])
    valid = violation <= 0.0                                                   # (R, C)
    episode_ok = limits.violations(cols["wage_parity"], cols["error_rate"], cols["energy_wh_per_unit"],
                                   cols["energy_wh"]) <= 0.0                  # (N, C)
    valid_fraction = table.run_means(episode_ok.astype(np.float64))

    masked = np.where(valid[:, None, :], utility[:, :, None], -np.inf)         # (R, K, C)
    best = np.argmax(masked, axis=0)
    best = np.where(valid.any(axis=0)[None, :], best, -1)
    with np.errstate(invalid="ignore"):
        penalised = utility[:, :, None] - PENALTY_SCALE * violation[:, None, :]
    fallback = np.argmax(np.nan_to_num(penalised, nan=-np.inf), axis=0)
    return ObjectiveSurface(table, tuple(objectives), tuple(sets), run_metrics, utility, valid,
                            valid_fraction, violation, best, fallback)


def parse_vector_objective(text: str, source: str = "--vector") -> Objective:
    """``"1,0.2,0.1,0.05,0"`` (``[mpl, error, energy, safety, novelty]``) -> an Objective."""
    try:
        values = [float(v) for v in text.replace(" ", ",").split(",") if v]
    except ValueError:
        raise ConfigError(source, None, f"expected 5 comma-separated numbers, got {text!r}") from None
    return Objective.from_vector(ObjectiveVector.from_list(values, source))


def objectives_from_options(presets: Sequence[str] = (), vectors: Sequence[str] = (), grid_divisions: int = 0,
                            include_novelty: bool = False, energy_term: str = "wh") -> list[Objective]:
    """Presets (comma lists allowed), explicit vectors and a simplex grid, all with ``energy_term``.

    Without presets or vectors all six presets are used (and the grid, if any, is added to them).
    """
    names = [n.strip() for p in presets for n in p.split(",") if n.strip()]
    out = preset_objectives(names) if names or not vectors else []
    out += [parse_vector_objective(v) for v in vectors]
    if grid_divisions:
        out += simplex_grid(grid_divisions, include_novelty)
    check_energy_term(energy_term, "--energy-term")
    return [o if o.energy_term == energy_term else replace(o, energy_term=energy_term) for o in out]


def evaluate_datapacks_under_constraints(
    datapacks: EpisodeTable | Iterable[Mapping[str, Any]],
    objective_vector: ObjectiveVector | Sequence[float] | str,
    constraint_set: ConstraintSet | Mapping[str, Any] | None,
) -> tuple[bool, float]:
    """Spec §5: ``valid, utility = evaluate_datapacks_under_constraints(datapacks, objective_vector,
    constraint_set)``.

    Scores recorded episodes (the episodes of the datapacks: an :class:`EpisodeTable`, or episode
    records / summaries as ``EpisodeTable.from_records`` reads them) pooled as one run, with
    :func:`solve_objective_surface`: ``utility`` is the mean episodic J under the objective
    (an ObjectiveVector, with its ``energy_term`` option; five weights; or a preset name) and
    ``valid`` says whether the episodes' mean wage parity, error rate and energy meet the
    constraint set (a ConstraintSet or the spec's mapping, e.g. ``{"max_error_rate": 0.05}``;
    ``None``: unconstrained).
    """
    if isinstance(objective_vector, str):
        objective_vector = ObjectiveVector.from_preset(objective_vector)
    elif not isinstance(objective_vector, ObjectiveVector):
        objective_vector = ObjectiveVector.from_list(list(objective_vector))
    if constraint_set is None:
        constraint_set = ConstraintSet(name="unconstrained")
    elif not isinstance(constraint_set, ConstraintSet):
        constraint_set = parse_constraint_set(constraint_set)
    records = datapacks.records() if isinstance(datapacks, EpisodeTable) else list(datapacks)
    pooled = EpisodeTable.from_records([{**rec, "run_id": "datapacks"} for rec in records], "<datapacks>")
    surface = solve_objective_surface(pooled, [Objective.from_vector(objective_vector)], [constraint_set])
    return bool(surface.valid[0, 0]), float(surface.utility[0, 0])
