"""EconomicObjectiveSpec and its compilation into a reward overlay.

Compilation (motor_backends spec, "Objective Overlay")::

    mpl_per_hour   <- +mpl_weight
    energy_kwh     <- -abs(energy_weight)
    error_rate     <- -abs(error_weight)
    novelty_score  <- +novelty_weight
    risk_score     <- -abs(risk_weight)
    <extra key>    <- extra_weights[key], as given

Zero scales are dropped. A backend's overlay reward at a step is
``sum_k scale_k * term_k(t)`` where each term is normalised so that its episodic
sum equals the episode metric of the same key.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from types import MappingProxyType

from econmotor.config.objective_profile import check_energy_term
from econmotor.errors import ConfigError

OVERLAY_KEYS: tuple[str, ...] = ("mpl_per_hour", "energy_kwh", "error_rate", "novelty_score", "risk_score")


@dataclass(frozen=True)
class EconomicObjectiveSpec:
    """What a unit of robot behaviour is worth, as weights on economic metrics.

    Attributes:
        mpl_weight: weight on throughput (good units per hour); positive rewards it.
        energy_weight: weight on electrical energy (kWh); always a penalty.
        error_weight: weight on the error rate; always a penalty.
        novelty_weight: weight on the novelty score; signed as given.
        risk_weight: weight on the risk score; always a penalty.
        extra_weights: further metric keys and their signed scales.
        name: a label recorded with runs and reports.
        energy_term: how J counts energy (not a weight): ``"wh"``, ``r_energy = -Wh`` (the default), or
            ``"usd"``, the task's electricity bill (:mod:`econmotor.config.objective_profile`); the J a
            report prints and held-out selection keeps a checkpoint by (``objectives.loader.objective_j``).
    """

    mpl_weight: float = 1.0
    energy_weight: float = 0.0
    error_weight: float = 0.0
    novelty_weight: float = 0.0
    risk_weight: float = 0.0
    extra_weights: Mapping[str, float] = field(default_factory=dict)
    name: str = "objective"
    energy_term: str = "wh"

    def __post_init__(self) -> None:
        check_energy_term(self.energy_term, "<objective>")
        for key in ("mpl_weight", "energy_weight", "error_weight", "novelty_weight", "risk_weight"):
            value = getattr(self, key)
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
                raise ConfigError("<objective>", key, f"must be a finite number, got {value!r}")
        extras = dict(self.extra_weights)
        for key, value in extras.items():
            if key in OVERLAY_KEYS:
                raise ConfigError("<objective>", f"extra_weights.{key}", "use the named weight for this metric")
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
                raise ConfigError("<objective>", f"extra_weights.{key}", f"must be a finite number, got {value!r}")
        object.__setattr__(self, "extra_weights", MappingProxyType(extras))

    def __hash__(self) -> int:
        return hash((self.mpl_weight, self.energy_weight, self.error_weight, self.novelty_weight,
                     self.risk_weight, tuple(sorted(self.extra_weights.items())), self.name, self.energy_term))

    def to_dict(self) -> dict:
        return {
            "name": self.name,
            "mpl_weight": self.mpl_weight,
            "energy_weight": self.energy_weight,
            "error_weight": self.error_weight,
            "novelty_weight": self.novelty_weight,
            "risk_weight": self.risk_weight,
            "extra_weights": dict(self.extra_weights),
            "energy_term": self.energy_term,
        }


@dataclass(frozen=True)
class CompiledRewardOverlay(Mapping[str, float]):
    """Metric key -> signed reward scale. Read-only mapping."""

    scales: Mapping[str, float]
    objective_name: str = "objective"

    def __post_init__(self) -> None:
        object.__setattr__(self, "scales", MappingProxyType(dict(self.scales)))

    def __getitem__(self, key: str) -> float:
        return self.scales[key]

    def __iter__(self) -> Iterator[str]:
        return iter(self.scales)

    def __len__(self) -> int:
        return len(self.scales)

    def __hash__(self) -> int:
        return hash(tuple(sorted(self.scales.items())))

    def weighted_sum(self, terms: Mapping[str, float]) -> float:
        """``sum_k scale_k * terms[k]`` over the overlay's keys (missing terms count 0)."""
        return float(sum(scale * terms.get(key, 0.0) for key, scale in self.scales.items()))

    def to_dict(self) -> dict[str, float]:
        return dict(self.scales)


def compile_economic_overlay(spec: EconomicObjectiveSpec) -> CompiledRewardOverlay:
    """Compile an objective into reward scales with the spec's signs (see module docstring)."""
    scales = {
        "mpl_per_hour": float(spec.mpl_weight),
        "energy_kwh": -abs(float(spec.energy_weight)),
        "error_rate": -abs(float(spec.error_weight)),
        "novelty_score": float(spec.novelty_weight),
        "risk_score": -abs(float(spec.risk_weight)),
    }
    scales = {k: v for k, v in scales.items() if v != 0.0}
    scales.update({k: float(v) for k, v in spec.extra_weights.items()})
    return CompiledRewardOverlay(scales, spec.name)
