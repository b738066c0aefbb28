"""Objective vectors, the economic context and reward weights.

An objective vector weights the five RewardBuilder terms in the fixed order
``[mpl, error, energy, safety, novelty]``. Presets (DESIGN.md §3):

============================  ==============================
preset                        [mpl, error, energy, safety, novelty]
============================  ==============================
throughput                    [2, 1, 0.5, 1, 0]
safety                        [0.5, 2, 1, 3, 0]
energy_saver                  [1, 1, 3, 1, 0]
balanced                      [1, 1, 1, 1, 0]
throughput_focused            [3, 0.5, 0.3, 0.5, 0]
premium_safety                [1, 3, 1, 5, 0]
============================  ==============================

Energy term option: an objective vector's ``energy_term`` says how ``r_energy`` is
measured. ``"wh"`` (the default, spec §1 and §7: "Wh consumed") makes it ``-Wh`` on every
task, priced or not; ``"usd"`` makes it the electricity bill, ``-(pi_e * Wh / 1000)`` USD
with the task's price ``pi_e`` (USD/kWh). Off by default: at 0.12 USD/kWh a 15 Wh episode
costs 0.0018 USD, so a priced energy term is invisible next to an MPL of 60 and no preset
can prefer a frugal run. Every J goes through :func:`econmotor.valuation.episode_j`, which
reads this option.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

from econmotor.errors import ConfigError, UnknownNameError

OBJECTIVE_TERMS: tuple[str, ...] = ("mpl", "error", "energy", "safety", "novelty")
#: how ``r_energy`` is measured (module docstring): Wh (default) or priced in USD.
ENERGY_TERMS: tuple[str, ...] = ("wh", "usd")
#: RewardWeights in the spec's §4 order (mpl, ep, error, energy, safety), then novelty.
REWARD_WEIGHT_NAMES: tuple[str, ...] = ("alpha_mpl", "alpha_ep", "alpha_error", "alpha_energy", "alpha_safety",
                                        "alpha_novelty")

OBJECTIVE_PRESETS: dict[str, tuple[float, float, float, float, float]] = {
    "throughput": (2.0, 1.0, 0.5, 1.0, 0.0),
    "safety": (0.5, 2.0, 1.0, 3.0, 0.0),
    "energy_saver": (1.0, 1.0, 3.0, 1.0, 0.0),
    "balanced": (1.0, 1.0, 1.0, 1.0, 0.0),
    "throughput_focused": (3.0, 0.5, 0.3, 0.5, 0.0),
    "premium_safety": (1.0, 3.0, 1.0, 5.0, 0.0),
}


@dataclass(frozen=True)
class ObjectiveVector:
    """Non-negative weights on ``[mpl, error, energy, safety, novelty]``.

    The scalarisation is ``J = w_mpl*r_mpl + w_error*r_error + w_energy*r_energy
    + w_safety*r_safety + w_novelty*r_novelty`` with the RewardBuilder terms
    (whose penalty terms are already negative), so ``[1, 0, 0, 0, 0]`` recovers
    plain throughput and ``default_objective_vector()`` approximates the legacy reward.
    ``energy_term`` (``"wh"`` or ``"usd"``, module docstring) is not a weight: ``to_list()``
    stays the five weights.
    """

    w_mpl: float = 1.0
    w_error: float = 0.2
    w_energy: float = 0.1
    w_safety: float = 0.05
    w_novelty: float = 0.0
    energy_term: str = "wh"

    def __post_init__(self) -> None:
        check_energy_term(self.energy_term)
        for name in OBJECTIVE_WEIGHT_FIELDS:
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise ConfigError("<objective_vector>", name, f"expected a number, got {value!r}")
            if not math.isfinite(value) or value < 0:
                raise ConfigError("<objective_vector>", name, f"must be finite and >= 0, got {value}")

    def to_list(self) -> list[float]:
        return [self.w_mpl, self.w_error, self.w_energy, self.w_safety, self.w_novelty]

    @classmethod
    def from_list(cls, values: Sequence[float], source: str = "<objective_vector>",
                  energy_term: str = "wh") -> ObjectiveVector:
        """Build from five numbers in the order ``[mpl, error, energy, safety, novelty]``."""
        if isinstance(values, (str, bytes)) or not isinstance(values, Sequence) or len(values) != 5:
            raise ConfigError(
                source, "objective_vector", f"expected 5 numbers [mpl, error, energy, safety, novelty], got {values!r}"
            )
        for i, v in enumerate(values):
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v < 0:
                raise ConfigError(
                    source, f"objective_vector[{i}]", f"expected a finite number >= 0, got {v!r}"
                )
        if not any(values):
            raise ConfigError(source, "objective_vector", "all-zero weights value nothing; give at least one "
                              "weight > 0", "5 finite numbers >= 0, not all zero")
        return cls(*(float(v) for v in values), energy_term=energy_term)

    @classmethod
    def from_preset(cls, name: str, energy_term: str = "wh") -> ObjectiveVector:
        """Return one of the six presets (see module docstring)."""
        if name not in OBJECTIVE_PRESETS:
            raise UnknownNameError("objective preset", name, OBJECTIVE_PRESETS)
        return cls(*OBJECTIVE_PRESETS[name], energy_term=energy_term)

    def normalize(self) -> ObjectiveVector:
        """Scale onto the simplex (weights sum to 1). An all-zero vector is an error."""
        total = sum(self.to_list())
        if total <= 0:
            raise ConfigError("<objective_vector>", None, "cannot normalise an all-zero vector")
        return ObjectiveVector(*(v / total for v in self.to_list()), energy_term=self.energy_term)


OBJECTIVE_WEIGHT_FIELDS: tuple[str, ...] = ("w_mpl", "w_error", "w_energy", "w_safety", "w_novelty")


def check_energy_term(value: str, source: str = "<objective_vector>") -> str:
    """``value`` if it is one of :data:`ENERGY_TERMS`, else a ConfigError listing them."""
    if value not in ENERGY_TERMS:
        raise ConfigError(source, "energy_term", f"unknown energy term {value!r}", ENERGY_TERMS)
    return value


@dataclass(frozen=True)
class EconContext:
    """The market a policy is priced in (an input of EconObjectiveNet).

    Attributes:
        wage_human: human wage, USD/h.
        energy_price_kWh: electricity price, USD/kWh.
        market_region: market label, e.g. ``"US"``.
        task_family: task family label.
        customer_segment: customer segment label.
        baseline_mpl_human: human throughput, units/h.
        baseline_error_human: human error rate, errors per attempted unit.
    """

    wage_human: float = 18.0
    energy_price_kWh: float = 0.12
    market_region: str = "US"
    task_family: str = "dishwashing"
    customer_segment: str = "balanced"
    baseline_mpl_human: float = 60.0
    baseline_error_human: float = 0.05

    def __post_init__(self) -> None:
        for name in ("wage_human", "energy_price_kWh", "baseline_mpl_human", "baseline_error_human"):
            value = getattr(self, name)
            if not math.isfinite(value) or value < 0:
                raise ConfigError("<econ_context>", name, f"must be finite and >= 0, got {value}")

    def numeric_features(self) -> list[float]:
        """Numeric features in a fixed order: wage, energy price, human MPL, human error rate."""
        return [self.wage_human, self.energy_price_kWh, self.baseline_mpl_human, self.baseline_error_human]


@dataclass(frozen=True)
class RewardWeights:
    """Per-term scales in the spec's §4 order
    ``[alpha_mpl, alpha_ep, alpha_error, alpha_energy, alpha_safety]`` (what EconObjectiveNet
    outputs), then ``alpha_novelty``.

    ``reward = alpha_mpl*r_mpl + alpha_ep*r_ep + alpha_error*r_error + alpha_energy*r_energy
    + alpha_safety*r_safety + alpha_novelty*r_novelty`` over the RewardBuilder terms, where
    ``r_ep`` is the energy productivity (good units per kWh, ``MP_r / E_r``; an increment of
    the running value at step level). An objective vector has no EP weight, so
    :meth:`from_objective` (the identity mapping) and the analytic mapping set ``alpha_ep = 0``:
    the energy term already carries the energy, and EP on top would count it twice. A
    positive ``alpha_ep`` (given explicitly, or learned) adds it as one more weighted term.
    """

    alpha_mpl: float = 1.0
    alpha_ep: float = 0.0
    alpha_error: float = 0.2
    alpha_energy: float = 0.1
    alpha_safety: float = 0.05
    alpha_novelty: float = 0.0

    def __post_init__(self) -> None:
        for name in REWARD_WEIGHT_NAMES:
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
                raise ConfigError("<reward_weights>", name, f"expected a finite number, got {value!r}")

    def to_list(self) -> list[float]:
        """The six weights in :data:`REWARD_WEIGHT_NAMES` order (§4's five, then novelty)."""
        return [getattr(self, name) for name in REWARD_WEIGHT_NAMES]

    @classmethod
    def from_list(cls, values: Sequence[float]) -> RewardWeights:
        """From §4's five ``[alpha_mpl, alpha_ep, alpha_error, alpha_energy, alpha_safety]`` (novelty 0) or all six."""
        if len(values) not in (5, 6):
            raise ConfigError("<reward_weights>", None, "expected 5 values [alpha_mpl, alpha_ep, alpha_error, "
                              f"alpha_energy, alpha_safety] (+ alpha_novelty), got {len(values)}")
        return cls(*(float(v) for v in values))

    @classmethod
    def from_objective(cls, vector: ObjectiveVector | Sequence[float]) -> RewardWeights:
        """The identity mapping ``alpha = w`` (``alpha_ep = 0``): ``combine_reward(vector, terms)``."""
        w = vector.to_list() if isinstance(vector, ObjectiveVector) else [float(v) for v in vector]
        if len(w) != 5:
            raise ConfigError("<objective_vector>", None, f"expected 5 weights, got {len(w)}")
        return cls(alpha_mpl=w[0], alpha_ep=0.0, alpha_error=w[1], alpha_energy=w[2], alpha_safety=w[3],
                   alpha_novelty=w[4])
