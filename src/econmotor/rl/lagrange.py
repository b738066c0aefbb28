"""Lagrange multipliers for episode-level constraints (modelled on OmniSafe's ``Lagrange``).

One multiplier ``lambda_i >= 0`` per active constraint of a
:class:`~econmotor.valuation.ConstraintSet`. The constraint's signed cost of an
episode is ``g_i = value_i - limit_i`` for a maximum (``max_error_rate``,
``max_energy_Wh``) and ``g_i = limit_i - value_i`` for a minimum
(``min_wage_parity``): positive means violated. Dual ascent on the average over
the episodes since the last update::

    lambda_i <- clip(lambda_i + lr * mean(g_i), 0, upper)

so a multiplier rises while its constraint is violated on average and falls back
(to 0 at the floor) once it is met, as OmniSafe's ``update_lagrange_multiplier``
does with ``Jc - cost_limit`` followed by a clamp at 0. The learner's reward is
``r - sum_i lambda_i * g_i`` (see :mod:`econmotor.rl.shadow`), spread over the steps as
increments (:mod:`econmotor.rl.constraint_shaping`); SAC's replay buffer re-shapes replayed
steps with the current ``values`` (:mod:`econmotor.rl.relabel_buffer`), so a multiplier
update reaches every stored transition at once.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from econmotor.errors import ConfigError
from econmotor.valuation import ConstraintSet
from econmotor.valuation.reward_builder import summary_value


def signed_costs(constraints: ConstraintSet, summary: Mapping[str, Any]) -> dict[str, float]:
    """``g_i`` per active constraint of ``summary`` (positive = violated, negative = slack)."""
    out: dict[str, float] = {}
    if constraints.min_wage_parity is not None:
        out["min_wage_parity"] = constraints.min_wage_parity - summary_value(summary, "wage_parity")
    if constraints.max_error_rate is not None:
        out["max_error_rate"] = summary_value(summary, "error_rate") - constraints.max_error_rate
    if constraints.max_energy_Wh is not None:
        value = constraints.energy_value(summary)
        # no good unit: energy per unit is unbounded; count it as one limit's worth of violation
        out["max_energy_Wh"] = (value if math.isfinite(value) else 2 * constraints.max_energy_Wh) \
            - constraints.max_energy_Wh
    return out


@dataclass
class LagrangeMultipliers:
    """Dual-ascent multipliers, one per constraint name.

    Args:
        names: constraint names (e.g. ``ConstraintSet.active()``).
        lr: dual learning rate (multiplier change per unit of mean signed cost).
        init: starting value of every multiplier (>= 0).
        upper: cap on every multiplier (OmniSafe's ``lambda_upper_bound``).

    ``history`` holds the multiplier values after each :meth:`update` (constraint name ->
    lambda, nothing else).
    """

    names: tuple[str, ...]
    lr: float = 0.5
    init: float = 0.0
    upper: float = 100.0
    values: dict[str, float] = field(init=False)
    history: list[dict[str, float]] = field(init=False, default_factory=list)
    _pending: list[dict[str, float]] = field(init=False, default_factory=list)

    def __post_init__(self) -> None:
        self.names = tuple(self.names)
        for key, value in (("lr", self.lr), ("init", self.init), ("upper", self.upper)):
            if not math.isfinite(value) or value < 0:
                raise ConfigError("<lagrange>", key, f"must be finite and >= 0, got {value}")
        self.values = {name: min(self.init, self.upper) for name in self.names}

    def record(self, costs: Mapping[str, float]) -> None:
        """Add one episode's signed costs (keys must be the multiplier names)."""
        unknown = set(costs) - set(self.names)
        if unknown:
            raise ConfigError("<lagrange>", min(unknown), "no multiplier for this constraint", self.names)
        self._pending.append({k: float(v) for k, v in costs.items()})

    def update(self) -> dict[str, float]:
        """One dual-ascent step on the mean of the recorded episodes; returns the new values."""
        if not self._pending:
            return dict(self.values)
        for name in self.names:
            mean_cost = sum(ep.get(name, 0.0) for ep in self._pending) / len(self._pending)
            self.values[name] = min(self.upper, max(0.0, self.values[name] + self.lr * mean_cost))
        self.history.append(dict(self.values))  # multipliers only
        self._pending.clear()
        return dict(self.values)

    def penalty(self, costs: Mapping[str, float]) -> float:
        """``sum_i lambda_i * g_i`` (subtract it from the reward)."""
        return sum(self.values[name] * float(cost) for name, cost in costs.items())
