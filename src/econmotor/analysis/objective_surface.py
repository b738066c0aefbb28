"""The objective surface: re-score recorded episodes under many objectives and constraint sets.

For episodes ``i`` of runs ``r``, objectives ``k`` (weight vectors on
``[mpl, error, energy, safety, novelty]``) and constraint sets ``c``:

- reward terms (RewardBuilder, DESIGN.md §3), matrix ``T`` (N x 5)::

      T[i] = [mpl_i, -error_rate_i, -(pi_e_i * Wh_i / 1000) (or -Wh_i if no price),
              -1 if catastrophic_i else 0, novelty_i]

- utility of a run under an objective: the mean episodic ``J = combine_reward(w_k, T[i])``.
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
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from econmotor.analysis.episode_table import EpisodeTable
from econmotor.config.objective_profile import OBJECTIVE_PRESETS, ObjectiveVector
from econmotor.errors import ConfigError, UnknownNameError
from econmotor.valuation.constraints import PENALTY_SCALE, ConstraintSet
from econmotor.valuation.reward_builder import REWARD_TERM_NAMES


@dataclass(frozen=True)
class Objective:
    """A named weight vector on ``[mpl, error, energy, safety, novelty]``."""

    name: str
    weights: tuple[float, float, float, float, float]
    kind: str = "vector"  # "preset" | "grid" | "vector"

    def to_dict(self) -> dict:
        return {"name": self.name, "weights": list(self.weights), "kind": self.kind}


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


def reward_term_matrix(table: EpisodeTable) -> np.ndarray:
    """The RewardBuilder terms of every episode, (N, 5) in :data:`REWARD_TERM_NAMES` order."""
    cols = table.columns
    price = table.energy_price_usd_per_kwh
    wh = cols["energy_wh"]
    energy_term = np.where(np.isnan(price), -wh, -np.nan_to_num(price) * wh / 1000.0)
    return np.column_stack([cols["mpl_units_per_hour"], -cols["error_rate"], energy_term,
                            -table.catastrophic.astype(np.float64), cols["novelty_score"]])


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
    vector = ObjectiveVector.from_list(values, source)
    return Objective("w[" + ",".join(f"{v:g}" for v in vector.to_list()) + "]", tuple(vector.to_list()), "vector")


def objectives_from_options(presets: Sequence[str] = (), vectors: Sequence[str] = (), grid_divisions: int = 0,
                            include_novelty: bool = False) -> list[Objective]:
    """Presets (comma lists allowed), explicit vectors and a simplex grid.

    Without presets or vectors all six presets are used (and the grid, if any, is added to them).
    """
    names = [n.strip() for p in presets for n in p.split(",") if n.strip()]
    out = preset_objectives(names) if names or not vectors else []
    out += [parse_vector_objective(v) for v in vectors]
    if grid_divisions:
        out += simplex_grid(grid_divisions, include_novelty)
    return out
