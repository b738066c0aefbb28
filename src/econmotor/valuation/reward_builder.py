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
