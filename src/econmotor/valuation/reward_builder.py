"""RewardBuilder: an episode or step summary -> five reward terms -> one scalar.

Terms, in the objective-vector order ``[mpl, error, energy, safety, novelty]``:

- ``r_mpl = mpl`` (good units per hour)
- ``r_error = -error_rate``
- ``r_energy = -(pi_e * Wh / 1000)`` in USD when an electricity price is known,
  else ``-Wh``
- ``r_safety = -1`` when the episode (or step) ended in a catastrophe, else 0
- ``r_novelty = novelty``

``combine_reward(w, terms) = sum_i w_i * r_i``. With ``default_objective_vector()
= [1.0, 0.2, 0.1, 0.05, 0.0]`` a good episode (mpl 60, error 0.02, 15 Wh, no price,
no catastrophe) scores 58.496 and a bad one (20, 0.3, 40 Wh, catastrophic) 15.89.

These are *levels*: fed one step summary at a time they do not add up to the
episode. :class:`IncrementalRewardTerms` gives per-step terms whose episode sums are
exactly ``build_reward_terms(episode_summary)`` (the step reward for RL).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

from econmotor.config.objective_profile import ObjectiveVector, RewardWeights
from econmotor.errors import ConfigError

REWARD_TERM_NAMES: tuple[str, ...] = ("r_mpl", "r_error", "r_energy", "r_safety", "r_novelty")

#: summary field -> names accepted for it, first match wins.
SUMMARY_ALIASES: dict[str, tuple[str, ...]] = {
    "mpl": ("mpl", "mpl_episode", "mpl_units_per_hour", "mpl_t"),
    "error_rate": ("error_rate", "error_rate_episode", "error_rate_t"),
    "energy_wh": ("energy_Wh", "energy_wh", "Wh", "wh_t"),
    "novelty": ("novelty", "novelty_score"),
}
CATASTROPHIC_REASONS = frozenset({"catastrophic_error", "fall", "vase_broken"})


def default_objective_vector() -> list[float]:
    """``[1.0, 0.2, 0.1, 0.05, 0.0]``: approximates the legacy reward (spec §2)."""
    return [1.0, 0.2, 0.1, 0.05, 0.0]


def summary_value(summary: Mapping[str, Any] | Any, field: str, default: float = 0.0) -> float:
    """Read a numeric summary field by any of its aliases (mapping or attribute access)."""
    for name in SUMMARY_ALIASES.get(field, (field,)):
        value = summary.get(name) if isinstance(summary, Mapping) else getattr(summary, name, None)
        if value is not None:
            value = float(value)
            if not math.isfinite(value):
                raise ConfigError("<summary>", name, f"must be finite, got {value}")
            return value
    return default


def is_catastrophic(summary: Mapping[str, Any] | Any) -> bool:
    """True when the summary records a catastrophic end (or a broken vase)."""
    get = summary.get if isinstance(summary, Mapping) else lambda k, d=None: getattr(summary, k, d)
    if get("catastrophic", False) or get("vase_broken", False):
        return True
    return get("termination_reason", None) in CATASTROPHIC_REASONS


def build_reward_terms(summary: Mapping[str, Any] | Any, econ_params: Any = None) -> dict[str, float]:
    """Compute the five RewardBuilder terms of a step or episode summary.

    Args:
        summary: a mapping (or object) with ``mpl``/``mpl_episode``, ``error_rate``/
            ``error_rate_episode``, ``energy_Wh``, ``termination_reason`` and ``novelty``.
        econ_params: anything with ``energy_price_usd_per_kwh`` (EconParams,
            TaskEconomics); ``None`` or a ``None`` price makes ``r_energy = -Wh``.
    """
    wh = summary_value(summary, "energy_wh")
    price = getattr(econ_params, "energy_price_usd_per_kwh", None) if econ_params is not None else None
    return {
        "r_mpl": summary_value(summary, "mpl"),
        "r_error": -summary_value(summary, "error_rate"),
        "r_energy": -(price * wh / 1000.0) if price is not None else -wh,
        "r_safety": -1.0 if is_catastrophic(summary) else 0.0,
        "r_novelty": summary_value(summary, "novelty"),
    }


def combine_reward(
    vector: Sequence[float] | ObjectiveVector | RewardWeights, terms: Mapping[str, float]
) -> float:
    """``sum_i w_i * r_i`` over ``[r_mpl, r_error, r_energy, r_safety, r_novelty]``."""
    weights = vector.to_list() if hasattr(vector, "to_list") else list(vector)
    if len(weights) != len(REWARD_TERM_NAMES):
        raise ConfigError("<objective_vector>", None, f"expected 5 weights, got {len(weights)}")
    return float(sum(w * terms[name] for w, name in zip(weights, REWARD_TERM_NAMES, strict=True)))


class IncrementalRewardTerms:
    """Per-step RewardBuilder terms whose episode sums are the episode's terms (stateful).

    ``build_reward_terms`` reads *levels* (running MPL, error rate): summed over the
    steps of an episode they count the MPL once per step, and ``r_safety`` fires on
    every catastrophic step. This class instead differences the running episode
    metrics, so that for the step summaries ``s_1..s_T`` of one episode and its
    episode summary ``S`` (DESIGN §3: each term's episodic sum is the episode metric)::

        sum_t step(s_t)[k] == build_reward_terms(S)[k]        for every term k
        sum_t combine_reward(w, step(s_t)) == combine_reward(w, build_reward_terms(S))

    up to float rounding, for every weight vector ``w``. Scalarisation (MO-Gymnasium
    style): the undiscounted return under ``w = [1,0,0,0,0]`` is the episode MPL
    (units/h); ``[0,1,0,0,0]`` minus the episode error rate; ``[0,0,1,0,0]`` minus the
    episode energy cost (USD with a price, else Wh); ``[0,0,0,1,0]`` -1 for a
    catastrophic episode, else 0; ``[0,0,0,0,1]`` the episode novelty; and ``w`` = the
    objective vector gives the episode J.

    Step terms (the step summary keys of the dishwashing env and of
    ``econmotor.rl.step_summary.MujocoStepSummaryWrapper``):

    - ``r_mpl = mpl_t - mpl_{t-1}``: ``mpl_t`` is the running MPL (units/h), ``mpl_0 = 0``;
    - ``r_error = -(E_t/A_t - E_{t-1}/A_{t-1})`` with ``E_t``, ``A_t`` the sums of the
      step's ``errors`` and ``attempts`` so far (``0/0 = 0``);
    - ``r_energy = -(pi_e * Wh / 1000)`` USD, or ``-Wh`` when no price (``Wh`` = this step's);
    - ``r_safety = -1`` on the one step whose ``termination_reason`` is in
      :data:`CATASTROPHIC_REASONS` (or the first step with ``vase_broken``), else 0;
    - ``r_novelty = n_t - n_{t-1}`` with ``n_t`` the running novelty the episode summary
      reports: the step's ``novelty_running`` (MuJoCo: mean visit bonus so far); without
      it the step's ``overlay_terms["novelty_score"]`` is the increment itself (dishwashing:
      1/25 per newly visited (speed, care) cell, summing to the share of cells visited).

    Call :meth:`reset` at every episode start.
    """

    __slots__ = ("_attempts", "_caught", "_error_rate", "_errors", "_mpl", "_novelty")

    def __init__(self) -> None:
        self.reset()

    def reset(self) -> None:
        """Forget the episode so far (running MPL, counts, novelty, catastrophe flag)."""
        self._mpl = self._errors = self._attempts = self._error_rate = self._novelty = 0.0
        self._caught = False

    def step(self, step_summary: Mapping[str, Any], econ_params: Any = None) -> dict[str, float]:
        """The five terms of one step (see the class docstring); updates the running state.

        Args:
            step_summary: one step's summary (``mpl_t``, ``errors``, ``attempts``, ``Wh``,
                ``termination_reason``, novelty as above).
            econ_params: anything with ``energy_price_usd_per_kwh``; ``None`` (or a ``None``
                price) makes ``r_energy = -Wh``.
        """
        try:
            mpl = float(step_summary["mpl_t"])
            self._errors += float(step_summary["errors"])
            self._attempts += float(step_summary["attempts"])
        except KeyError as exc:
            raise ConfigError("<step_summary>", str(exc.args[0]), "incremental reward terms need the running "
                              "MPL and the step's counts", ["mpl_t", "errors", "attempts"]) from None
        error_rate = self._errors / self._attempts if self._attempts > 0 else 0.0
        novelty = step_summary.get("novelty_running")
        if novelty is not None:
            d_novelty, self._novelty = float(novelty) - self._novelty, float(novelty)
        else:
            d_novelty = float((step_summary.get("overlay_terms") or {}).get("novelty_score", 0.0))
        catastrophe = not self._caught and (step_summary.get("termination_reason") in CATASTROPHIC_REASONS
                                            or bool(step_summary.get("vase_broken", False)))
        self._caught = self._caught or catastrophe
        wh = summary_value(step_summary, "energy_wh")
        price = getattr(econ_params, "energy_price_usd_per_kwh", None) if econ_params is not None else None
        terms = {
            "r_mpl": mpl - self._mpl,
            "r_error": -(error_rate - self._error_rate),
            "r_energy": -(price * wh / 1000.0) if price is not None else -wh,
            "r_safety": -1.0 if catastrophe else 0.0,
            "r_novelty": d_novelty,
        }
        self._mpl, self._error_rate = mpl, error_rate
        return terms
