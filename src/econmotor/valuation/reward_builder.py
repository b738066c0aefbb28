"""RewardBuilder: an episode or step summary -> reward terms -> one scalar, and an episode's J.

Terms, in the objective-vector order ``[mpl, error, energy, safety, novelty]``:

- ``r_mpl = mpl`` (good units per hour)
- ``r_error = -error_rate``
- ``r_energy = -Wh`` (spec §1, §7: "Wh consumed", on every task, priced or not); only an
  objective whose ``energy_term`` is ``"usd"`` (an explicit option, off by default, see
  :mod:`econmotor.config.objective_profile`) prices it: ``-(pi_e * Wh / 1000)`` USD
- ``r_safety = -1`` when the episode (or step) ended in a catastrophe, else 0
- ``r_novelty = novelty``

plus ``r_ep``, the energy productivity (good units per kWh), which only
:class:`~econmotor.config.objective_profile.RewardWeights` weights (``alpha_ep``).

``combine_reward(w, terms) = sum_i w_i * r_i``. With ``default_objective_vector()
= [1.0, 0.2, 0.1, 0.05, 0.0]`` a good episode (mpl 60, error 0.02, 15 Wh, no
catastrophe) scores 58.496 and a bad one (20, 0.3, 40 Wh, catastrophic) 15.89 (spec §7,
check 1), on any task.

:func:`episode_j` is the one function that computes an episode's J from its summary,
the objective and the task economics: shadow mode, the solver (vectorised through
:func:`reward_terms_from_metrics`, the one place the term formulas live), sweeps and the
report call it.

These are *levels*: fed one step summary at a time they do not add up to the
episode. :class:`IncrementalRewardTerms` gives per-step terms whose episode sums are
exactly ``build_reward_terms(episode_summary)`` (the step reward for RL).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from econmotor.config.objective_profile import ObjectiveVector, RewardWeights, check_energy_term
from econmotor.economics.termination import TerminationReason
from econmotor.errors import ConfigError

REWARD_TERM_NAMES: tuple[str, ...] = ("r_mpl", "r_error", "r_energy", "r_safety", "r_novelty")
#: the terms RewardWeights scale, in its order (spec §4: mpl, ep, error, energy, safety; then novelty).
WEIGHTED_TERM_NAMES: tuple[str, ...] = ("r_mpl", "r_ep", "r_error", "r_energy", "r_safety", "r_novelty")

#: summary field -> names accepted for it, first match wins.
SUMMARY_ALIASES: dict[str, tuple[str, ...]] = {
    "mpl": ("mpl", "mpl_episode", "mpl_units_per_hour", "mpl_t"),
    "error_rate": ("error_rate", "error_rate_episode", "error_rate_t"),
    "energy_wh": ("energy_Wh", "energy_wh", "Wh", "wh_t"),
    "ep": ("ep", "ep_episode", "energy_productivity_units_per_kwh", "ep_t"),
    "novelty": ("novelty", "novelty_score"),
}
CATASTROPHIC_REASONS = frozenset({TerminationReason.CATASTROPHIC_ERROR, TerminationReason.FALL, "vase_broken"})


def default_objective_vector() -> list[float]:
    """``[1.0, 0.2, 0.1, 0.05, 0.0]``: approximates the legacy reward (spec §2)."""
    return [1.0, 0.2, 0.1, 0.05, 0.0]


def _get(summary: Mapping[str, Any] | Any, name: str) -> Any:
    return summary.get(name) if isinstance(summary, Mapping) else getattr(summary, name, None)


def summary_value(summary: Mapping[str, Any] | Any, field: str, default: float = 0.0) -> float:
    """Read a numeric summary field by any of its aliases (mapping or attribute access)."""
    for name in SUMMARY_ALIASES.get(field, (field,)):
        value = _get(summary, name)
        if value is not None:
            value = float(value)
            if not math.isfinite(value):
                raise ConfigError("<summary>", name, f"must be finite, got {value}")
            return value
    return default


def energy_productivity_value(summary: Mapping[str, Any] | Any) -> float:
    """The summary's energy productivity (units/kWh); 0 when absent or not finite (no energy used)."""
    for name in SUMMARY_ALIASES["ep"]:
        value = _get(summary, name)
        if value is not None:
            value = float(value)
            return value if math.isfinite(value) else 0.0
    return 0.0


def is_catastrophic(summary: Mapping[str, Any] | Any) -> bool:
    """True when the summary records a catastrophic end (or a broken vase)."""
    if _get(summary, "catastrophic") or _get(summary, "vase_broken"):
        return True
    return _get(summary, "termination_reason") in CATASTROPHIC_REASONS


def energy_price_of(economics: Any) -> float | None:
    """``economics.energy_price_usd_per_kwh`` (TaskEconomics, EconParams, ...), or ``None``."""
    return getattr(economics, "energy_price_usd_per_kwh", None) if economics is not None else None


def reward_terms_from_metrics(mpl: Any, error_rate: Any, energy_wh: Any, catastrophic: Any, novelty: Any,
                              ep: Any = 0.0, *, energy_term: str = "wh",
                              energy_price_usd_per_kwh: Any = None) -> dict[str, Any]:
    """The term formulas (module docstring), on floats or on equal-shaped NumPy arrays.

    Args:
        mpl: good units per hour. error_rate: errors per attempted unit. energy_wh: Wh.
        catastrophic: bool (or bool array). novelty: novelty score. ep: units per kWh.
        energy_term: ``"wh"`` (default: ``r_energy = -Wh``) or ``"usd"`` (``-(pi_e * Wh / 1000)``).
        energy_price_usd_per_kwh: ``pi_e``, needed (finite) only with ``energy_term="usd"``.
    """
    check_energy_term(energy_term)
    if energy_term == "usd":
        price = np.asarray(np.nan if energy_price_usd_per_kwh is None else energy_price_usd_per_kwh, dtype=float)
        if not np.all(np.isfinite(price)):
            raise ConfigError("<task economics>", "energy_price_usd_per_kwh", "the objective prices energy "
                              "(energy_term: usd) but the task has no electricity price; set one or use "
                              "energy_term: wh")
        energy = -(price * energy_wh / 1000.0)
    else:
        energy = -energy_wh
    return {"r_mpl": mpl, "r_ep": ep, "r_error": -error_rate, "r_energy": energy,
            "r_safety": 0.0 - 1.0 * catastrophic, "r_novelty": novelty}


def build_reward_terms(summary: Mapping[str, Any] | Any, econ_params: Any = None,
                       energy_term: str = "wh") -> dict[str, float]:
    """Compute the RewardBuilder terms of a step or episode summary.

    Args:
        summary: a mapping (or object) with ``mpl``/``mpl_episode``, ``error_rate``/
            ``error_rate_episode``, ``energy_Wh``, ``termination_reason``, ``novelty`` and
            (for ``r_ep``) ``ep_episode`` / ``energy_productivity_units_per_kwh``.
        econ_params: the task economics (TaskEconomics, EconParams: anything with
            ``energy_price_usd_per_kwh``); read only when ``energy_term == "usd"``.
        energy_term: ``"wh"`` (default, ``r_energy = -Wh``) or ``"usd"`` (priced).
    """
    terms = reward_terms_from_metrics(
        summary_value(summary, "mpl"), summary_value(summary, "error_rate"), summary_value(summary, "energy_wh"),
        is_catastrophic(summary), summary_value(summary, "novelty"), energy_productivity_value(summary),
        energy_term=energy_term, energy_price_usd_per_kwh=energy_price_of(econ_params))
    return {k: float(v) for k, v in terms.items()}


def objective_weights(vector: Sequence[float] | ObjectiveVector | RewardWeights) -> dict[str, float]:
    """Term name -> weight: five objective weights, or RewardWeights' six (with ``r_ep``)."""
    if isinstance(vector, RewardWeights):
        return dict(zip(WEIGHTED_TERM_NAMES, vector.to_list(), strict=True))
    weights = vector.to_list() if hasattr(vector, "to_list") else list(vector)
    if len(weights) != len(REWARD_TERM_NAMES):
        raise ConfigError("<objective_vector>", None, f"expected 5 weights, got {len(weights)}")
    return dict(zip(REWARD_TERM_NAMES, (float(w) for w in weights), strict=True))


def combine_terms(vector: Sequence[float] | ObjectiveVector | RewardWeights, terms: Mapping[str, Any]) -> Any:
    """``sum_i w_i * r_i``: over ``[r_mpl, r_error, r_energy, r_safety, r_novelty]`` for an objective
    vector, over ``[r_mpl, r_ep, r_error, r_energy, r_safety, r_novelty]`` for RewardWeights; on floats
    or on equal-shaped NumPy arrays of terms (:func:`reward_terms_from_metrics`)."""
    return sum(w * terms[name] for name, w in objective_weights(vector).items())


def combine_reward(
    vector: Sequence[float] | ObjectiveVector | RewardWeights, terms: Mapping[str, float]
) -> float:
    """:func:`combine_terms` as one float."""
    return float(combine_terms(vector, terms))


def energy_term_of(objective: Any) -> str:
    """The objective's ``energy_term`` option (``"wh"`` for plain weight lists)."""
    return getattr(objective, "energy_term", "wh")


def episode_j(summary: Mapping[str, Any] | Any, objective: Sequence[float] | ObjectiveVector | RewardWeights,
              economics: Any = None, energy_term: str | None = None) -> float:
    """An episode's J: ``combine_reward(objective, build_reward_terms(summary, economics, energy_term))``.

    The one place J is computed (shadow mode, solver, sweeps, report).

    Args:
        summary: the episode summary (keys as :func:`build_reward_terms` reads them).
        objective: an ObjectiveVector (its ``energy_term`` option applies), five weights
            ``[mpl, error, energy, safety, novelty]``, or RewardWeights.
        economics: the task economics (its electricity price is read only for ``energy_term="usd"``).
        energy_term: overrides the objective's option (``None``: the objective's, else ``"wh"``).
    """
    term = energy_term if energy_term is not None else energy_term_of(objective)
    return combine_reward(objective, build_reward_terms(summary, economics, term))


def extract_step_summary(info: Mapping[str, Any]) -> dict[str, Any]:
    """The step summary in a step's ``info`` (spec §3: ``step_summary = extract_step_summary(info)``).

    Every env econmotor trains on writes ``info["step_summary"]`` (the dishwashing workcell
    itself; MuJoCo tasks through ``econmotor.motor_backend.mujoco.step_summary.MujocoStepSummaryWrapper``).
    Returns a copy; ``build_reward_terms`` and ``IncrementalRewardTerms.step`` read it.
    """
    if not isinstance(info, Mapping):
        raise ConfigError("<info>", None, f"expected the step's info mapping, got {type(info).__name__}")
    summary = info.get("step_summary")
    if not isinstance(summary, Mapping):
        raise ConfigError("<info>", "step_summary", "no per-step summary in info; wrap MuJoCo envs in "
                          "econmotor.motor_backend.mujoco.step_summary.MujocoStepSummaryWrapper")
    return dict(summary)


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
    episode energy (Wh; USD with ``energy_term="usd"``); ``[0,0,0,1,0]`` -1 for a
    catastrophic episode, else 0; ``[0,0,0,0,1]`` the episode novelty; and ``w`` = the
    objective vector gives the episode J.

    Step terms (the step summary keys of the dishwashing env and of
    ``econmotor.motor_backend.mujoco.step_summary.MujocoStepSummaryWrapper``):

    - ``r_mpl = mpl_t - mpl_{t-1}``: ``mpl_t`` is the running MPL (units/h), ``mpl_0 = 0``;
    - ``r_error = -(E_t/A_t - E_{t-1}/A_{t-1})`` with ``E_t``, ``A_t`` the sums of the
      step's ``errors`` and ``attempts`` so far (``0/0 = 0``);
    - ``r_energy = -Wh`` (this step's), or ``-(pi_e * Wh / 1000)`` USD with ``energy_term="usd"``;
    - ``r_safety = -1`` on the one step whose ``termination_reason`` is in
      :data:`CATASTROPHIC_REASONS` (or the first step with ``vase_broken``), else 0;
    - ``r_novelty = n_t - n_{t-1}`` with ``n_t`` the running novelty the episode summary
      reports: the step's ``novelty_running`` (MuJoCo: mean visit bonus so far); without
      it the step's ``overlay_terms["novelty_score"]`` is the increment itself (dishwashing:
      1/25 per newly visited (speed, care) cell, summing to the share of cells visited);
    - ``r_ep = ep_t - ep_{t-1}``: ``ep_t`` the running energy productivity (units/kWh) the
      step reports (``ep_t``; 0 when absent or not finite), ``ep_0 = 0``.

    Call :meth:`reset` at every episode start.
    """

    __slots__ = ("_attempts", "_caught", "_ep", "_error_rate", "_errors", "_mpl", "_novelty")

    def __init__(self) -> None:
        self.reset()

    def reset(self) -> None:
        """Forget the episode so far (running MPL, counts, novelty, catastrophe flag)."""
        self._mpl = self._errors = self._attempts = self._error_rate = self._novelty = self._ep = 0.0
        self._caught = False

    def step(self, step_summary: Mapping[str, Any], econ_params: Any = None,
             energy_term: str = "wh") -> dict[str, float]:
        """The terms of one step (see the class docstring); updates the running state.

        Args:
            step_summary: one step's summary (``mpl_t``, ``errors``, ``attempts``, ``Wh``,
                ``termination_reason``, novelty and ``ep_t`` as above).
            econ_params: the task economics; its price is read only with ``energy_term="usd"``.
            energy_term: ``"wh"`` (default) or ``"usd"``, as in :func:`build_reward_terms`.
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
        ep = energy_productivity_value({"ep_t": step_summary.get("ep_t")})
        terms = reward_terms_from_metrics(
            mpl - self._mpl, error_rate - self._error_rate, summary_value(step_summary, "energy_wh"), catastrophe,
            d_novelty, ep - self._ep, energy_term=energy_term, energy_price_usd_per_kwh=energy_price_of(econ_params))
        self._mpl, self._error_rate, self._ep = mpl, error_rate, ep
        return {k: float(v) for k, v in terms.items()}
