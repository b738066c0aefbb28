"""How a constraint set reaches the learner's reward: ``penalty`` or ``lagrangian``.

Constraints are defined on episode summaries (``econmotor.valuation.ConstraintSet``),
but SAC credits rewards per step, and a penalty paid only on the last step of a
240-step episode reaches the first step discounted by ``0.99**240 ~ 0.09``. So the
shaping is **spread over the steps**, as increments of the *running episode*
violation, the way :class:`econmotor.valuation.reward_builder.IncrementalRewardTerms`
spreads the objective terms. After step ``t`` the running episode metrics are

- error rate ``E_t / A_t`` (errors and attempts so far, ``0/0 = 0``);
- wage parity: the step summary's ``wage_parity_running`` (implied wage of the running
  MPL and error rate / human wage, as the episode summary computes it);
- energy ``W_t`` Wh so far (``per_episode``) or ``W_t / U_t`` Wh per good unit so far
  (``per_unit``; no good unit yet counts as one limit's worth of violation, the
  convention of :func:`econmotor.rl.lagrange.signed_costs`, so the reward stays finite).

With ``v_t = sum_i violation_i(running metrics after t)``, ``v_0 = 0``, and signed costs
``g_i(t)`` (positive = violated), ``g_i(0) = 0``:

- ``penalty`` (spec §5): ``r_t <- r_t - 10 * (v_t - v_{t-1})``;
- ``lagrangian``: ``r_t <- r_t - sum_i lambda_i * (g_i(t) - g_i(t-1))``; at the end of
  each episode the multipliers take a dual-ascent step on the *episode summary's* signed
  costs (every ``update_every_episodes`` episodes, on their mean), never mid-episode.

**Invariant** (the sums telescope): over the steps of one episode with summary ``S``,
``sum_t penalty_t == 10 * sum(constraints.violations(S).values())``, i.e. the shaped
return is ``apply_constraint_penalties(return, S, constraints)``, and in ``lagrangian``
mode ``sum_t penalty_t == sum_i lambda_i * signed_costs(constraints, S)[i]``: the
constraint weighs on the episode exactly as the episode-level formula does, on the
same scale as the episode-sized objective return. (Exception: an episode with no good
unit under a ``per_unit`` energy limit, whose episode violation is infinite, is
charged one limit's worth.)

**Off-policy relabelling** (``lagrangian``): the step's signed-cost increments
``g_i(t) - g_i(t-1)`` are kept in :attr:`ConstraintShaper.last_increments`; the shadow
wrapper puts them with the unshaped reward into ``info`` so that
:class:`econmotor.rl.relabel_buffer.LagrangeRelabelReplayBuffer` can recompute a replayed
step's reward with the multipliers current at sample time (SAC replays transitions long
after the multipliers they were shaped with have moved).

The running state restarts at :meth:`ConstraintShaper.reset` (the shadow wrapper calls it
at every env reset) and after :meth:`ConstraintShaper.end_episode`.
Either way, the episode-level violations are reported per episode.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

from econmotor.errors import ConfigError
from econmotor.rl.lagrange import LagrangeMultipliers, signed_costs
from econmotor.valuation import ConstraintSet
from econmotor.valuation.constraints import PENALTY_SCALE

CONSTRAINT_MODES = ("penalty", "lagrangian")
_COUNT_KEYS = ("errors", "attempts", "units", "Wh")


class RunningEpisodeView:
    """The running episode metrics a ConstraintSet reads, from step summaries (stateful)."""

    __slots__ = ("attempts", "errors", "units", "wh")

    def __init__(self) -> None:
        self.reset()

    def reset(self) -> None:
        self.errors = self.attempts = self.units = self.wh = 0.0

    def step(self, step_summary: Mapping[str, Any], need_wage: bool) -> dict[str, float]:
        """Add one step's counts; return ``error_rate``, ``wage_parity``, ``energy_Wh``,
        ``energy_Wh_per_unit`` of the episode so far."""
        try:
            self.errors += float(step_summary["errors"])
            self.attempts += float(step_summary["attempts"])
            self.units += float(step_summary["units"])
            self.wh += float(step_summary["Wh"])
        except KeyError as exc:
            raise ConfigError("<step_summary>", str(exc.args[0]), "constraint shaping needs the step's counts",
                              _COUNT_KEYS) from None
        view = {
            "error_rate": self.errors / self.attempts if self.attempts > 0 else 0.0,
            "energy_Wh": self.wh,
            "energy_Wh_per_unit": self.wh / self.units if self.units > 0 else math.inf,
        }
        if need_wage:
            if step_summary.get("wage_parity_running") is None:
                raise ConfigError("<step_summary>", "wage_parity_running", "min_wage_parity shaping needs the "
                                  "running episode wage parity in the step summary", ["wage_parity_running"])
            view["wage_parity"] = float(step_summary["wage_parity_running"])
        return view


class ConstraintShaper:
    """Apply a constraint set to step rewards and keep its multipliers (module docstring).

    Args:
        constraints: the limits.
        mode: ``"penalty"`` or ``"lagrangian"``.
        lagrange_lr: dual learning rate (``lagrangian``).
        lagrange_init: starting multipliers (``lagrangian``).
        update_every_episodes: episodes averaged per dual step (``lagrangian``).
    """

    def __init__(self, constraints: ConstraintSet, mode: str = "penalty",
                 lagrange_lr: float = 1.0, lagrange_init: float = 0.0, update_every_episodes: int = 1) -> None:
        if mode not in CONSTRAINT_MODES:
            raise ConfigError("--constraint-mode", None, f"unknown mode {mode!r}", CONSTRAINT_MODES)
        if not constraints.active():
            raise ConfigError(constraints.name, None, "the constraint set has no active constraint",
                              ["min_wage_parity", "max_error_rate", "max_energy_Wh"])
        self.constraints, self.mode = constraints, mode
        self.multipliers = LagrangeMultipliers(tuple(constraints.active()), lr=lagrange_lr, init=lagrange_init)
        self.update_every = max(1, int(update_every_episodes))
        self._episodes = 0
        self._view = RunningEpisodeView()
        self.reset()

    def reset(self) -> None:
        """Start a new episode: running metrics and the previous violation / costs back to 0."""
        self._view.reset()
        self._prev_violation = 0.0
        self._prev_costs = dict.fromkeys(self.constraints.active(), 0.0)
        self.last_increments: dict[str, float] = {}

    def running_violation(self, view: Mapping[str, float]) -> float:
        """``sum_i violation_i`` of the running metrics (an infinite one counts as its limit)."""
        out = 0.0
        for name, value in self.constraints.violations(view).items():
            out += value if math.isfinite(value) else float(getattr(self.constraints, name))
        return out

    def step_penalty(self, step_summary: Mapping[str, Any]) -> float:
        """The amount this step's reward loses (an increment: it may be negative)."""
        view = self._view.step(step_summary, self.constraints.min_wage_parity is not None)
        if self.mode == "penalty":
            violation = self.running_violation(view)
            delta, self._prev_violation = violation - self._prev_violation, violation
            return PENALTY_SCALE * delta
        costs = signed_costs(self.constraints, view)
        delta = {k: v - self._prev_costs[k] for k, v in costs.items()}
        self._prev_costs, self.last_increments = costs, delta
        return self.multipliers.penalty(delta)

    def step_reward(self, reward: float, step_summary: Mapping[str, Any]) -> float:
        """The learner's step reward after the constraint shaping."""
        return reward - self.step_penalty(step_summary)

    def end_episode(self, episode_summary: Mapping[str, Any]) -> dict[str, Any]:
        """Report the episode's violations; in ``lagrangian`` mode, record and maybe update.
        The running state restarts for the next episode."""
        self.reset()
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
