"""Constraint sets on episode summaries, and the soft penalty of spec §5.

A constraint set (YAML)::

    min_wage_parity: 0.9      # implied wage / human wage, at least
    max_error_rate: 0.05      # errors / attempted units, at most
    max_energy_Wh: 20.0       # Wh, at most ...
    energy_basis: per_unit    # ... per good unit (default) or per_episode

Penalty (spec §5): ``reward - 10 * sum(violations)`` where a violation is
``max(0, limit - value)`` for a minimum and ``max(0, value - limit)`` for a maximum.
A constraint-sets file holds several named sets under ``constraint_sets:``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

from econmotor.config.loading import as_float, as_str, check_keys, read_yaml_mapping, require_mapping
from econmotor.valuation.reward_builder import summary_value

PENALTY_SCALE = 10.0
ENERGY_BASES = ("per_unit", "per_episode")
_KEYS = ("min_wage_parity", "max_error_rate", "max_energy_Wh", "energy_basis", "name")


@dataclass(frozen=True)
class ConstraintSet:
    """Limits checked on an episode summary; ``None`` means unconstrained."""

    min_wage_parity: float | None = None
    max_error_rate: float | None = None
    max_energy_Wh: float | None = None
    energy_basis: str = "per_unit"
    name: str = "constraints"

    def active(self) -> list[str]:
        """Names of the constraints that are set."""
        return [k for k in ("min_wage_parity", "max_error_rate", "max_energy_Wh") if getattr(self, k) is not None]

    def energy_value(self, summary: Mapping[str, Any] | Any) -> float:
        """The summary's energy on this set's basis (Wh per good unit or Wh per episode)."""
        if self.energy_basis == "per_episode":
            return summary_value(summary, "energy_wh")
        for name in ("energy_Wh_per_unit", "energy_wh_per_unit"):
            value = summary.get(name) if isinstance(summary, Mapping) else getattr(summary, name, None)
            if value is not None:
                return float(value)
        return math.inf

    def violations(self, summary: Mapping[str, Any] | Any) -> dict[str, float]:
        """Non-negative violation per active constraint (0 when met)."""
        out: dict[str, float] = {}
        if self.min_wage_parity is not None:
            parity = summary_value(summary, "wage_parity", default=0.0)
            out["min_wage_parity"] = max(0.0, self.min_wage_parity - parity)
        if self.max_error_rate is not None:
            out["max_error_rate"] = max(0.0, summary_value(summary, "error_rate") - self.max_error_rate)
        if self.max_energy_Wh is not None:
            out["max_energy_Wh"] = max(0.0, self.energy_value(summary) - self.max_energy_Wh)
        return out

    def satisfied(self, summary: Mapping[str, Any] | Any) -> bool:
        return all(v <= 0.0 for v in self.violations(summary).values())

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


def apply_constraint_penalties(reward: float, summary: Mapping[str, Any] | Any,
                               constraints: ConstraintSet | Mapping[str, Any]) -> float:
    """``reward - 10 * sum(violations)`` (spec §5) for min_wage_parity, max_error_rate, max_energy_Wh."""
    if not isinstance(constraints, ConstraintSet):
        constraints = parse_constraint_set(constraints)
    return reward - PENALTY_SCALE * sum(constraints.violations(summary).values())


def parse_constraint_set(data: Any, source: str | Path = "<constraints>", prefix: str | None = None,
                         name: str = "constraints") -> ConstraintSet:
    """Validate one constraint-set mapping."""
    data = require_mapping(data, source, prefix)
    check_keys(data, _KEYS, source, prefix)
    key = lambda k: f"{prefix}.{k}" if prefix else k
    values: dict[str, Any] = {}
    if data.get("min_wage_parity") is not None:
        values["min_wage_parity"] = as_float(data["min_wage_parity"], source, key("min_wage_parity"))
    if data.get("max_error_rate") is not None:
        values["max_error_rate"] = as_float(data["max_error_rate"], source, key("max_error_rate"),
                                            min_value=0.0, max_value=1.0)
    if data.get("max_energy_Wh") is not None:
        values["max_energy_Wh"] = as_float(data["max_energy_Wh"], source, key("max_energy_Wh"), min_value=0.0)
    basis = as_str(data.get("energy_basis", "per_unit"), source, key("energy_basis"), ENERGY_BASES)
    set_name = as_str(data.get("name", name), source, key("name"))
    return ConstraintSet(**values, energy_basis=basis, name=set_name)


def load_constraint_set(path: str | Path) -> ConstraintSet:
    """Load one constraint set from YAML (schema in the module docstring)."""
    return parse_constraint_set(read_yaml_mapping(path), path, name=Path(path).stem)


def load_constraint_sets(path: str | Path) -> list[ConstraintSet]:
    """Load several named sets: ``constraint_sets: {name: {...}, ...}`` (or one bare set)."""
    data = read_yaml_mapping(path)
    if "constraint_sets" not in data:
        return [parse_constraint_set(data, path, name=Path(path).stem)]
    check_keys(data, ("constraint_sets",), path)
    sets = require_mapping(data["constraint_sets"], path, "constraint_sets")
    return [parse_constraint_set(v if v is not None else {}, path, f"constraint_sets.{k}", name=str(k))
            for k, v in sets.items()]
