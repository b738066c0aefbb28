"""The analytic dishwashing workcell: a robot trades speed against care (Gymnasium API).

Action ``Box([0, 0], [1, 1])`` = (speed, care). Per step of ``time_step_s`` seconds::

    rate     = max(0.1, base_rate*(0.5 + 0.5*speed)) * (1 - care_cost*care)   attempts/min
    attempts = max(1, Poisson(rate * time_step_s / 60))
    p_err    = clip(p_min + k_err * speed**q_speed * (1 - care)**q_care, 0, 0.5)
    errors   ~ Binomial(attempts, p_err);  completed += attempts - errors
    Wh      += attempts * energy_Wh_per_attempt

A step is catastrophic when ``errors == attempts``. Termination, checked in order:
``catastrophic_error`` (catastrophic steps >= max_catastrophic_errors),
``sla_violation`` (steps >= min_steps_for_sla, completed > 0 and errors/completed >
max_error_rate_sla), ``zero_throughput`` (steps >= zero_throughput_patience and nothing
completed), then ``max_steps`` (a truncation). All randomness comes from the
environment's seeded generator, so ``reset(seed=s)`` plus the same actions replays an episode.

Rewards (``reward_mode``):

- ``"overlay"``: ``sum_k scale_k * term_k(t) / ref_k`` with the compiled
  :class:`~econmotor.objectives.EconomicObjectiveSpec` scales and
  ``ref_k = term_references[k]`` (default 1). Terms (``info["overlay_terms"]``) are
  normalised so their episode sum is the episode metric of the same key:
  ``mpl_per_hour`` = change of running MPL (sums to episode MPL, units/h);
  ``energy_kwh`` = step kWh; ``error_rate`` = change of the running errors/attempts;
  ``risk_score`` = catastrophic-step indicator / max_catastrophic_errors, plus the rest
  of the budget on a step that ends the episode in a failure (episode value: the share of
  the catastrophe budget used, and 1 for any failure termination: catastrophe, SLA
  violation or zero throughput — so ending a shift early is never a way to save risk);
  ``novelty_score`` = 1/25 when the step's action falls in a 5x5 (speed, care) cell not
  yet visited this episode (episode value: share of cells visited); extra keys
  ``energy_kwh_per_hour`` (change of the running kWh per hour worked, summing to the
  episode's kWh/h), ``profit_usd`` (step profit) and ``units_completed`` (step good
  units). Other extra keys
  of an objective have no meaning here: they contribute 0 and are listed in
  :attr:`DishwashingEnv.ignored_overlay_keys`.
- ``"legacy"``: :func:`econmotor.economics.compute_econ_reward` on the step summary
  (``d_mpl``, ``error_rate_t``, ``implied_wage_t``, ``wage_human``).
- ``"reward_builder"``: ``combine_reward(objective_vector, IncrementalRewardTerms.step(step_summary,
  econ_params, energy_term))`` — change of the running MPL, minus the change of the running error
  rate, minus the step's Wh (its cost in USD only when ``objective_vector`` is an ObjectiveVector
  with ``energy_term="usd"``, at ``econ_params.energy_price_usd_per_kwh``), -1 once on a
  catastrophic end, the step's novelty increment. The terms are increments of the running
  episode metrics (reset at every ``reset``), so the episode return is the episode J:
  ``sum_t r_t == episode_j(episode_summary, objective_vector, econ_params)``.

The step summary also carries the running episode values a constraint reads
(``error_rate_running``, ``implied_wage_running``, ``wage_parity_running``), computed
as the episode summary computes them, so that ``econmotor.rl.constraint_shaping`` can
charge increments of the running episode violation.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any, ClassVar

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from econmotor.config.econ_params import EconParams
from econmotor.config.objective_profile import ObjectiveVector
from econmotor.economics import labour
from econmotor.economics.legacy_reward import LegacyRewardWeights, compute_econ_reward
from econmotor.economics.termination import TerminationReason
from econmotor.envs.dishwashing_randomization import EconRandomization
from econmotor.errors import ConfigError
from econmotor.objectives.economic_objective import EconomicObjectiveSpec, compile_economic_overlay
from econmotor.objectives.loader import objective_from_vector
from econmotor.valuation.reward_builder import (
    IncrementalRewardTerms,
    combine_reward,
    default_objective_vector,
    energy_term_of,
)

REWARD_MODES = ("overlay", "legacy", "reward_builder")
TERMINATION_REASONS = (TerminationReason.CATASTROPHIC_ERROR, TerminationReason.SLA_VIOLATION,
                       TerminationReason.ZERO_THROUGHPUT, TerminationReason.MAX_STEPS)
FAILURE_REASONS = TERMINATION_REASONS[:3]
OVERLAY_TERM_KEYS = ("mpl_per_hour", "energy_kwh", "error_rate", "risk_score", "novelty_score",
                     "energy_kwh_per_hour", "profit_usd", "units_completed")
NOVELTY_GRID = 5
OBS_NAMES = ("time_frac", "units_per_step", "attempts_per_step", "error_rate_running",
             "last_attempts", "last_error_rate", "catastrophe_budget_used", "sla_pressure",
             "zero_throughput_pressure")
OBS_HIGH = 5.0


def expected_attempts_per_step(params: EconParams, speed: float, care: float) -> float:
    """E[max(1, Poisson(lam))] = lam + exp(-lam), lam = rate * time_step_s / 60."""
    lam = attempt_rate_per_min(params, speed, care) * params.time_step_s / 60.0
    return lam + float(np.exp(-lam))


def attempt_rate_per_min(params: EconParams, speed: float, care: float) -> float:
    """max(0.1, base_rate*(0.5 + 0.5*speed)) * (1 - care_cost*care), attempts/min."""
    return max(0.1, params.base_rate * (0.5 + 0.5 * speed)) * (1.0 - params.care_cost * care)


def error_probability(params: EconParams, speed: float, care: float) -> float:
    """clip(p_min + k_err * speed**q_speed * (1 - care)**q_care, 0, 0.5)."""
    p = params.p_min + params.k_err * speed ** params.q_speed * (1.0 - care) ** params.q_care
    return float(np.clip(p, 0.0, 0.5))


class DishwashingEnv(gym.Env):
    """The dishwashing workcell (see the module docstring for dynamics and rewards).

    Args:
        econ_params: workcell and economics parameters (default: preset ``toy``).
        reward_mode: ``"overlay"``, ``"legacy"`` or ``"reward_builder"``.
        objective: the objective compiled into the overlay (``overlay`` mode; default:
            built from ``objective_vector`` if given, else ``mpl_weight=1``).
        objective_vector: ``[mpl, error, energy, safety, novelty]`` weights or an ObjectiveVector
            (``reward_builder`` mode; default :func:`default_objective_vector`).
        legacy_weights: alpha, beta, gamma (``legacy`` mode).
        max_steps: episode length limit; default ``econ_params.max_steps``.
        render_mode: ``None`` or ``"ansi"``.
        randomization: per-episode EconParams randomization (drawn at every reset).
        term_references: overlay key -> reference value dividing that term in the reward
            (e.g. the human MPL for ``mpl_per_hour``); info terms stay unscaled.
    """

    metadata: ClassVar[dict[str, Any]] = {"render_modes": ["ansi"]}

    def __init__(
        self,
        econ_params: EconParams | None = None,
        reward_mode: str = "overlay",
        objective: EconomicObjectiveSpec | None = None,
        objective_vector: Sequence[float] | ObjectiveVector | None = None,
        legacy_weights: LegacyRewardWeights | None = None,
        max_steps: int | None = None,
        render_mode: str | None = None,
        randomization: EconRandomization | None = None,
        term_references: Mapping[str, float] | None = None,
    ) -> None:
        super().__init__()
        if reward_mode not in REWARD_MODES:
            raise ConfigError("<DishwashingEnv>", "reward_mode", f"unknown reward mode {reward_mode!r}", REWARD_MODES)
        if render_mode not in (None, "ansi"):
            raise ConfigError("<DishwashingEnv>", "render_mode", f"unsupported {render_mode!r}", ["ansi"])
        self.base_params = econ_params or EconParams.preset("toy")
        self.params = self.base_params
        self.max_steps = int(max_steps if max_steps is not None else self.base_params.max_steps)
        if self.max_steps < 1:
            raise ConfigError("<DishwashingEnv>", "max_steps", f"must be >= 1, got {self.max_steps}")
        self.reward_mode = reward_mode
        self.render_mode = render_mode
        self.randomization = randomization
        self.legacy_weights = legacy_weights or LegacyRewardWeights()
        self.energy_term = energy_term_of(objective_vector)
        if isinstance(objective_vector, ObjectiveVector):
            objective_vector = objective_vector.to_list()
        self.objective_vector = list(objective_vector) if objective_vector is not None else default_objective_vector()
        if len(self.objective_vector) != 5:
            raise ConfigError("<DishwashingEnv>", "objective_vector",
                              f"expected 5 weights [mpl, error, energy, safety, novelty], got {self.objective_vector}")
        if objective is None:
            objective = (objective_from_vector(ObjectiveVector.from_list(objective_vector))
                         if objective_vector is not None else EconomicObjectiveSpec())
        self.objective = objective
        self.overlay = compile_economic_overlay(objective)
        self.ignored_overlay_keys = tuple(k for k in self.overlay if k not in OVERLAY_TERM_KEYS)
        self.term_references = {k: 1.0 for k in OVERLAY_TERM_KEYS}
        for key, ref in dict(term_references or {}).items():
            if key not in OVERLAY_TERM_KEYS or not ref > 0:
                raise ConfigError("<DishwashingEnv>", f"term_references.{key}",
                                  f"must be an overlay term key with a value > 0, got {ref!r}", OVERLAY_TERM_KEYS)
            self.term_references[key] = float(ref)
        self.action_space = spaces.Box(0.0, 1.0, shape=(2,), dtype=np.float32)
        self.observation_space = spaces.Box(0.0, OBS_HIGH, shape=(len(OBS_NAMES),), dtype=np.float32)
        self._env_steps = 0
        self.incremental_terms = IncrementalRewardTerms()
        self._reset_counters()

    # ------------------------------------------------------------------ state
    def _reset_counters(self) -> None:
        self.t = 0
        self.units = self.attempts = self.errors = self.catastrophic_steps = 0
        self.energy_wh = 0.0
        self.profit_usd = 0.0
        self.episode_return = 0.0
        self.mpl_running = 0.0
        self.error_rate_running = 0.0
        self.kwh_per_hour_running = 0.0
        self.last_attempts = 0
        self.last_error_rate = 0.0
        self.visited_cells: set[tuple[int, int]] = set()
        self.incremental_terms.reset()

    def _obs(self) -> np.ndarray:
        p = self.params
        ref = max(1.0, p.base_rate * p.time_step_s / 60.0)
        steps = max(1, self.t)
        sla = (self.errors / self.units / p.max_error_rate_sla) if self.units and p.max_error_rate_sla > 0 else 0.0
        zero = min(1.0, self.t / max(1, p.zero_throughput_patience)) if self.units == 0 else 0.0
        obs = np.array([
            self.t / self.max_steps,
            self.units / steps / ref,
            self.attempts / steps / ref,
            self.error_rate_running,
            self.last_attempts / ref,
            self.last_error_rate,
            self.catastrophic_steps / max(1, p.max_catastrophic_errors),
            sla,
            zero,
        ], dtype=np.float32)
        return np.clip(obs, 0.0, OBS_HIGH)

    # -------------------------------------------------------------- gym API
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        super().reset(seed=seed)
        if self.randomization is not None:
            self.params = self.randomization.sample(self.base_params, self.np_random, self._env_steps)
        self._reset_counters()
        return self._obs(), {"econ_params": self.params.to_dict()}

    def step(self, action):
        p, rng = self.params, self.np_random
        a = np.clip(np.asarray(action, dtype=np.float64).reshape(-1), 0.0, 1.0)
        if a.shape != (2,) or not np.all(np.isfinite(a)):
            raise ValueError(f"action must be 2 finite numbers (speed, care), got {action!r}")
        speed, care = float(a[0]), float(a[1])
        lam = attempt_rate_per_min(p, speed, care) * p.time_step_s / 60.0
        attempts = max(1, int(rng.poisson(lam)))
        p_err = error_probability(p, speed, care)
        errors = int(rng.binomial(attempts, p_err))
        units = attempts - errors
        catastrophic = errors == attempts
        wh = attempts * p.energy_Wh_per_attempt

        self.t += 1
        self._env_steps += 1
        self.units += units
        self.attempts += attempts
        self.errors += errors
        self.catastrophic_steps += int(catastrophic)
        self.energy_wh += wh
        summary = self._step_summary(speed, care, units, errors, attempts, wh, catastrophic)

        reason = self._termination_reason()
        terminated = reason is not None and reason != TerminationReason.MAX_STEPS
        truncated = reason == TerminationReason.MAX_STEPS
        summary["termination_reason"] = reason
        if terminated:
            summary["overlay_terms"]["risk_score"] += 1.0 - self._catastrophe_share()
        reward = self._reward(summary)
        self.episode_return += reward
        self.last_attempts, self.last_error_rate = attempts, errors / attempts
        info: dict[str, Any] = {"step_summary": summary, "overlay_terms": summary["overlay_terms"]}
        if reason is not None:
            info["episode_summary"] = self.episode_summary(reason)
        return self._obs(), float(reward), terminated, truncated, info

    def _step_summary(self, speed: float, care: float, units: int, errors: int, attempts: int,
                      wh: float, catastrophic: bool) -> dict[str, Any]:
        p = self.params
        dt_h = p.time_step_s / 3600.0
        mpl_prev, err_prev, kwh_h_prev = self.mpl_running, self.error_rate_running, self.kwh_per_hour_running
        self.mpl_running = labour.mpl_units_per_hour(self.units, self.t * dt_h)
        self.kwh_per_hour_running = self.energy_wh / 1000.0 / (self.t * dt_h)
        self.error_rate_running = labour.error_rate(self.errors, self.attempts)
        err_step = errors / attempts
        mpl_step = units / dt_h
        wage = labour.implied_wage(p.price_per_unit, mpl_step, p.damage_cost, err_step)
        wage_running = labour.implied_wage(p.price_per_unit, self.mpl_running, p.damage_cost,
                                           self.error_rate_running)
        price = p.energy_price_usd_per_kwh or 0.0
        profit = p.price_per_unit * units - p.damage_cost * errors - price * wh / 1000.0
        self.profit_usd += profit
        cell = (min(int(speed * NOVELTY_GRID), NOVELTY_GRID - 1), min(int(care * NOVELTY_GRID), NOVELTY_GRID - 1))
        novel = cell not in self.visited_cells
        self.visited_cells.add(cell)
        terms = {
            "mpl_per_hour": self.mpl_running - mpl_prev,
            "energy_kwh": wh / 1000.0,
            "error_rate": self.error_rate_running - err_prev,
            "risk_score": float(catastrophic) / max(1, p.max_catastrophic_errors),
            "novelty_score": float(novel) / NOVELTY_GRID**2,
            "energy_kwh_per_hour": self.kwh_per_hour_running - kwh_h_prev,
            "profit_usd": profit,
            "units_completed": float(units),
        }
        return {
            "t": self.t, "speed": speed, "care": care,
            "units": units, "errors": errors, "attempts": attempts, "Wh": wh, "Wh_cumulative": self.energy_wh,
            "mpl_t": self.mpl_running, "d_mpl": terms["mpl_per_hour"], "mpl_step": mpl_step,
            "error_rate_t": err_step, "error_rate_running": self.error_rate_running,
            "implied_wage_t": wage, "wage_human": p.wage_human,
            "wage_parity_t": labour.wage_parity(wage, p.wage_human),
            "implied_wage_running": wage_running,
            "wage_parity_running": labour.wage_parity(wage_running, p.wage_human),
            "ep_t": labour.energy_productivity(self.mpl_running, self.kwh_per_hour_running),
            "profit": profit, "profit_cumulative": self.profit_usd,
            "catastrophic": catastrophic, "overlay_terms": terms,
        }

    def _catastrophe_share(self) -> float:
        return self.catastrophic_steps / max(1, self.params.max_catastrophic_errors)

    def _termination_reason(self) -> str | None:
        p = self.params
        if self.catastrophic_steps >= p.max_catastrophic_errors:
            return TerminationReason.CATASTROPHIC_ERROR
        if self.t >= p.min_steps_for_sla and self.units > 0 and self.errors / self.units > p.max_error_rate_sla:
            return TerminationReason.SLA_VIOLATION
        if self.t >= p.zero_throughput_patience and self.units == 0:
            return TerminationReason.ZERO_THROUGHPUT
        if self.t >= self.max_steps:
            return TerminationReason.MAX_STEPS
        return None

    def _reward(self, summary: Mapping[str, Any]) -> float:
        if self.reward_mode == "overlay":
            terms = summary["overlay_terms"]
            return float(sum(scale * terms.get(k, 0.0) / self.term_references.get(k, 1.0)
                             for k, scale in self.overlay.items()))
        if self.reward_mode == "legacy":
            return compute_econ_reward(summary["d_mpl"], summary["error_rate_t"], summary["implied_wage_t"],
                                       summary["wage_human"], self.legacy_weights)
        return combine_reward(self.objective_vector,
                              self.incremental_terms.step(summary, self.params, self.energy_term))

    def episode_summary(self, termination_reason: str | None = None) -> dict[str, Any]:
        """The episode so far: the meter's raw keys plus the RewardBuilder fields.

        ``mpl_episode`` units/h, ``ep_episode`` units/kWh, ``energy_Wh`` Wh,
        ``energy_Wh_per_unit`` Wh/unit (inf with no unit), ``profit`` USD,
        ``wage_parity`` = implied wage / human wage, ``risk_score`` = catastrophic steps /
        max_catastrophic_errors (1 after any failure termination), ``novelty_score`` = share
        of (speed, care) cells visited.
        """
        p = self.params
        hours = self.t * p.time_step_s / 3600.0
        mpl = labour.mpl_units_per_hour(self.units, hours)
        err = labour.error_rate(self.errors, self.attempts)
        wage = labour.implied_wage(p.price_per_unit, mpl, p.damage_cost, err)
        kwh_per_h = self.energy_wh / 1000.0 / hours if hours > 0 else 0.0
        return {
            "units_completed": float(self.units),
            "units_attempted": float(self.attempts),
            "errors": float(self.errors),
            "episode_length_s": self.t * p.time_step_s,
            "energy_wh": self.energy_wh,
            "length_steps": float(self.t),
            "risk_score": 1.0 if termination_reason in FAILURE_REASONS else self._catastrophe_share(),
            "novelty_score": len(self.visited_cells) / NOVELTY_GRID**2,
            "return": self.episode_return,
            "termination_reason": termination_reason,
            "catastrophic_steps": float(self.catastrophic_steps),
            "mpl_episode": mpl,
            "ep_episode": labour.energy_productivity(mpl, kwh_per_h),
            "error_rate_episode": err,
            "energy_Wh": self.energy_wh,
            "energy_kwh": self.energy_wh / 1000.0,
            "energy_kwh_per_hour": kwh_per_h,
            "energy_Wh_per_unit": self.energy_wh / self.units if self.units else float("inf"),
            "profit": self.profit_usd,
            "implied_wage_usd_per_hour": wage,
            "wage_parity": labour.wage_parity(wage, p.wage_human),
        }

    def render(self) -> str | None:
        if self.render_mode != "ansi":
            return None
        return (f"t={self.t} units={self.units} attempts={self.attempts} errors={self.errors} "
                f"Wh={self.energy_wh:.2f} mpl={self.mpl_running:.1f}/h")
