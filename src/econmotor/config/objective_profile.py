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
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass

from econmotor.errors import ConfigError, UnknownNameError

OBJECTIVE_TERMS: tuple[str, ...] = ("mpl", "error", "energy", "safety", "novelty")

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
    """

    w_mpl: float = 1.0
    w_error: float = 0.2
    w_energy: float = 0.1
    w_safety: float = 0.05
    w_novelty: float = 0.0

    def __post_init__(self) -> None:
        for name, value in asdict(self).items():
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise ConfigError("<objective_vector>", name, f"expected a number, got {value!r}")
            if not math.isfinite(value) or value < 0:
                raise ConfigError("<objective_vector>", name, f"must be finite and >= 0, got {value}")

    def to_list(self) -> list[float]:
        return [self.w_mpl, self.w_error, self.w_energy, self.w_safety, self.w_novelty]

    @classmethod
    def from_list(cls, values: Sequence[float], source: str = "<objective_vector>") -> ObjectiveVector:
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
        return cls(*(float(v) for v in values))

    @classmethod
    def from_preset(cls, name: str) -> ObjectiveVector:
        """Return one of the six presets (see module docstring)."""
        if name not in OBJECTIVE_PRESETS:
            raise UnknownNameError("objective preset", name, OBJECTIVE_PRESETS)
        return cls(*OBJECTIVE_PRESETS[name])

    def normalize(self) -> ObjectiveVector:
        """Scale onto the simplex (weights sum to 1). An all-zero vector is an error."""
        total = sum(self.to_list())
        if total <= 0:
            raise ConfigError("<objective_vector>", None, "cannot normalise an all-zero vector")
        return ObjectiveVector(*(v / total for v in self.to_list()))


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
    """Positive per-term scales applied to the RewardBuilder terms.

    ``reward = alpha_mpl*r_mpl + alpha_error*r_error + alpha_energy*r_energy
    + alpha_safety*r_safety + alpha_novelty*r_novelty``.
    """

    alpha_mpl: float = 1.0
    alpha_error: float = 0.2
    alpha_energy: float = 0.1
    alpha_safety: float = 0.05
    alpha_novelty: float = 0.0

    def to_list(self) -> list[float]:
        return [self.alpha_mpl, self.alpha_error, self.alpha_energy, self.alpha_safety, self.alpha_novelty]

    @classmethod
    def from_list(cls, values: Sequence[float]) -> RewardWeights:
        if len(values) != 5:
            raise ConfigError("<reward_weights>", None, f"expected 5 values, got {len(values)}")
        return cls(*(float(v) for v in values))
