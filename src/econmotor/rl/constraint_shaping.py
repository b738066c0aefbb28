"""How a constraint set reaches the learner's reward: ``penalty`` or ``lagrangian``.

Constraints are defined on episode summaries (``econmotor.valuation.ConstraintSet``),
but SAC credits rewards per step, and a penalty paid only on the last step of a
240-step episode reaches the first step discounted by ``0.99**240 ~ 0.09``. So the
shaping is **spread over the steps**: every step's own summary is checked against
the same limits (error rate, wage parity and Wh per good unit are rates, so a step's
value is on the episode's scale; a ``per_episode`` energy budget is split evenly,
``max_energy_Wh / steps_per_episode`` per step, so the step costs of a full episode
sum to the episode's).

- ``penalty`` (spec §5): ``r_t <- apply_constraint_penalties(r_t, step_summary, constraints)``
  ``= r_t - 10 * sum_i max(0, violation_i(t))``.
- ``lagrangian``: ``r_t <- r_t - sum_i lambda_i * g_i(t)`` with signed costs ``g_i``
  (:func:`econmotor.rl.lagrange.signed_costs`); at the end of each episode the
  multipliers take a dual-ascent step on the *episode summary's* signed costs
  (every ``update_every_episodes`` episodes, on their mean).

Either way, the episode-level violations are reported per episode.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from typing import Any

from econmotor.errors import ConfigError
from econmotor.rl.lagrange import LagrangeMultipliers, signed_costs
from econmotor.valuation import ConstraintSet, apply_constraint_penalties

CONSTRAINT_MODES = ("penalty", "lagrangian")


def constraint_view(step_summary: Mapping[str, Any]) -> dict[str, float]:
    """The fields a ConstraintSet reads, from a step summary (dishwashing key set)."""
    units = float(step_summary.get("units", 0.0))
    wh = float(step_summary.get("Wh", 0.0))
    return {
        "error_rate": float(step_summary.get("error_rate_t", 0.0)),
        "wage_parity": float(step_summary.get("wage_parity_t", 0.0)),
        "energy_Wh": wh,
        "energy_Wh_per_unit": wh / units if units > 0 else math.inf,
    }


class ConstraintShaper:
    """Apply a constraint set to step rewards and keep its multipliers (module docstring).

    Args:
        constraints: the limits.
        mode: ``"penalty"`` or ``"lagrangian"``.
        steps_per_episode: episode length limit, to split a ``per_episode`` energy budget.
        lagrange_lr: dual learning rate (``lagrangian``).
        lagrange_init: starting multipliers (``lagrangian``).
        update_every_episodes: episodes averaged per dual step (``lagrangian``).
    """

    def __init__(self, constraints: ConstraintSet, mode: str = "penalty", steps_per_episode: int = 1,
                 lagrange_lr: float = 1.0, lagrange_init: float = 0.0, update_every_episodes: int = 1) -> None:
        if mode not in CONSTRAINT_MODES:
            raise ConfigError("--constraint-mode", None, f"unknown mode {mode!r}", CONSTRAINT_MODES)
        if not constraints.active():
            raise ConfigError(constraints.name, None, "the constraint set has no active constraint",
                              ["min_wage_parity", "max_error_rate", "max_energy_Wh"])
        self.constraints, self.mode = constraints, mode
        self.step_constraints = constraints
        if constraints.max_energy_Wh is not None and constraints.energy_basis == "per_episode":
            self.step_constraints = dataclasses.replace(
                constraints, max_energy_Wh=constraints.max_energy_Wh / max(1, int(steps_per_episode)))
        self.multipliers = LagrangeMultipliers(tuple(constraints.active()), lr=lagrange_lr, init=lagrange_init)
        self.update_every = max(1, int(update_every_episodes))
        self._episodes = 0

    def step_reward(self, reward: float, step_summary: Mapping[str, Any]) -> float:
        """The learner's step reward after the constraint shaping."""
        view = constraint_view(step_summary)
        if self.mode == "penalty":
            return apply_constraint_penalties(reward, view, self.step_constraints)
        return reward - self.multipliers.penalty(signed_costs(self.step_constraints, view))

    def end_episode(self, episode_summary: Mapping[str, Any]) -> dict[str, Any]:
        """Report the episode's violations; in ``lagrangian`` mode, record and maybe update."""
        costs = signed_costs(self.constraints, episode_summary)
        out: dict[str, Any] = {
            "violations": self.constraints.violations(episode_summary),
            "signed_costs": costs,
            "satisfied": self.constraints.satisfied(episode_summary),
        }
        if self.mode == "lagrangian":
            self.multipliers.record(costs)
            self._episodes += 1
            if self._episodes % self.update_every == 0:
                self.multipliers.update()
            out["multipliers"] = dict(self.multipliers.values)
        return out
