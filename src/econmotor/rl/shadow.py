"""Shadow mode: both rewards from the same step summary; the flip picks the learner's.

At every step :class:`ShadowRewardWrapper` reads ``info["step_summary"]`` (the
dishwashing key set: ``d_mpl``, ``error_rate_t``, ``implied_wage_t``,
``wage_human``, ``mpl_t``, ``Wh``, ``catastrophic``, ...; MuJoCo tasks get it from
:class:`econmotor.motor_backend.mujoco.step_summary.MujocoStepSummaryWrapper`) and computes

- legacy: ``alpha*d_mpl - beta*error_rate_t - gamma*|implied_wage_t/wage_human - 1|``
  via :func:`econmotor.economics.compute_econ_reward`;
- objective: ``combine_reward(reward_weights, IncrementalRewardTerms.step(step_summary, economics,
  energy_term))``, every term kept (``reward_weights``, RewardWeights in the spec's §4 order
  with ``alpha_ep``, from the episode's objective vector: identity, analytic or
  EconObjectiveNet). The incremental terms (change of the running MPL, energy productivity
  and error rate, the step's Wh, -1 once on a catastrophic end, change of the running
  novelty) sum over an episode to ``build_reward_terms(episode_summary)``,
  so ``objective_sum == combine_reward(reward_weights, episode_terms)`` and, with
  ``identity`` weights, ``objective_sum == episode_J``: the objective return is the
  episode J, as the legacy ``alpha*dMP`` term sums to the episode MPL.

The learner sees ``legacy`` unless ``use_objective_reward`` (the flip), then the
constraint shaping (:mod:`econmotor.rl.constraint_shaping`) if any; in ``lagrangian``
mode ``info["lagrange_relabel"]`` carries the step's unshaped learner reward and its
signed-cost increments, which
:class:`~econmotor.rl.relabel_buffer.LagrangeRelabelReplayBuffer` uses to re-shape
replayed steps with the current multipliers (the returned reward is unchanged). Nothing else
changes with the flip: the same summaries, sums and logs. At the end of an episode
the wrapper builds the record (both sums, learner sum, per-term totals raw and
weighted, episode J = :func:`~econmotor.valuation.reward_builder.episode_j` of the episode
summary under the episode's objective vector and the task economics — the same function
``econmotor solve`` scores the exported episode with — the econ summary, constraint
violations and multipliers) and hands it to the :class:`~econmotor.rl.shadow_log.ShadowRecorder`.
The energy term is Wh unless the run's objective option ``energy_term`` is ``"usd"``.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

import gymnasium as gym

from econmotor.analysis.episode_table import SHADOW_EPISODE_FORMAT  # ``econmotor solve`` reads these records
from econmotor.config.objective_profile import ObjectiveVector, RewardWeights
from econmotor.config.task_economics import TaskEconomics
from econmotor.economics.legacy_reward import LegacyRewardWeights, compute_econ_reward
from econmotor.economics.meter import EconomicMeter
from econmotor.errors import ConfigError
from econmotor.motor_backend.results import episode_summary
from econmotor.rl.conditioning import ObjectiveConditioningWrapper
from econmotor.rl.constraint_shaping import ConstraintShaper
from econmotor.rl.relabel_buffer import RELABEL_INFO_KEY
from econmotor.rl.shadow_log import ShadowRecorder
from econmotor.valuation.reward_builder import (
    WEIGHTED_TERM_NAMES,
    IncrementalRewardTerms,
    build_reward_terms,
    combine_reward,
    energy_price_of,
    episode_j,
    extract_step_summary,
    objective_weights,
)

WeightsFn = Callable[[ObjectiveVector], RewardWeights]
ECON_SUMMARY_KEYS = ("mpl_episode", "error_rate_episode", "energy_Wh", "energy_Wh_per_unit", "wage_parity",
                     "implied_wage_usd_per_hour", "units_completed", "units_attempted", "errors",
                     "episode_length_s", "termination_reason", "profit", "risk_score", "novelty_score",
                     "ep_episode", "energy_productivity_units_per_kwh")



def legacy_step_reward(step_summary: Mapping[str, Any], weights: LegacyRewardWeights) -> float:
    """The legacy training-economics reward of one step summary."""
    return compute_econ_reward(step_summary["d_mpl"], step_summary["error_rate_t"],
                               step_summary["implied_wage_t"], step_summary["wage_human"], weights)


def find_conditioning(env: gym.Env) -> ObjectiveConditioningWrapper | None:
    """The ObjectiveConditioningWrapper inside ``env``'s wrapper chain, or None."""
    while env is not None:
        if isinstance(env, ObjectiveConditioningWrapper):
            return env
        env = getattr(env, "env", None)
    return None


class ShadowRewardWrapper(gym.Wrapper):
    """Compute the legacy and the objective reward every step; hand one to the learner.

    Args:
        env: an env whose ``info["step_summary"]`` has the dishwashing key set; if an
            :class:`~econmotor.rl.conditioning.ObjectiveConditioningWrapper` is inside, its
            per-episode vector is used, else ``objective``.
        economics: the task economics from the catalog (episode summaries when the env gives only
            raw metrics; the electricity price when the energy term is priced).
        weights_for: objective vector -> RewardWeights (identity / analytic / net).
        objective: the vector when the env is not conditioned (normalised here); its
            ``energy_term`` (``"wh"`` default, or ``"usd"``) applies to every episode of the run.
        task_id: the task id written into each episode record (for ``econmotor solve``).
        use_objective_reward: the flip: the learner sees the objective reward.
        legacy_weights: alpha, beta, gamma of the legacy reward.
        constraints: constraint shaping of the learner's reward, or ``None``.
        recorder: where episode records go (``None``: a memory-only recorder).
    """

    def __init__(self, env: gym.Env, *, economics: TaskEconomics, weights_for: WeightsFn,
                 objective: ObjectiveVector, use_objective_reward: bool = False,
                 legacy_weights: LegacyRewardWeights | None = None,
                 constraints: ConstraintShaper | None = None, recorder: ShadowRecorder | None = None,
                 task_id: str = "") -> None:
        super().__init__(env)
        self.economics, self.meter, self.task_id = economics, EconomicMeter(economics), task_id
        self.weights_for = weights_for
        self.energy_term = objective.energy_term
        self.fixed_objective = objective.normalize()
        self.use_objective_reward = bool(use_objective_reward)
        self.legacy_weights, self.constraints = legacy_weights or LegacyRewardWeights(), constraints
        self.recorder = recorder if recorder is not None else ShadowRecorder()
        self._conditioning = find_conditioning(env)
        self.incremental = IncrementalRewardTerms()
        self.episode_index = 0
        self._start_episode()

    def _start_episode(self) -> None:
        self.vector = self._conditioning.objective_vector if self._conditioning else self.fixed_objective
        self.weights = self.weights_for(self.vector)
        self.legacy_sum = self.objective_sum = self.learner_sum = 0.0
        self.term_sums = dict.fromkeys(WEIGHTED_TERM_NAMES, 0.0)
        self.incremental.reset()
        if self.constraints is not None:  # a reset mid-episode must not carry the running violation over
            self.constraints.reset()
        self.steps = 0

    def reset(self, **kwargs: Any):
        obs, info = self.env.reset(**kwargs)
        self._start_episode()
        return obs, info

    def step(self, action):
        obs, _env_reward, terminated, truncated, info = self.env.step(action)
        summary = extract_step_summary(info)
        legacy = legacy_step_reward(summary, self.legacy_weights)
        terms = self.incremental.step(summary, self.economics, self.energy_term)
        objective = combine_reward(self.weights, terms)
        reward = objective if self.use_objective_reward else legacy
        if self.constraints is not None:
            unshaped = reward
            reward = self.constraints.step_reward(reward, summary)
            if self.constraints.mode == "lagrangian":  # for the relabelling replay buffer
                info[RELABEL_INFO_KEY] = {"reward_unshaped": unshaped,
                                          "cost_increments": dict(self.constraints.last_increments)}
        self.steps += 1
        self.legacy_sum += legacy
        self.objective_sum += objective
        self.learner_sum += reward
        for name in WEIGHTED_TERM_NAMES:
            self.term_sums[name] += terms[name]
        self.recorder.add_step(legacy, objective)
        info["shadow"] = {"legacy": legacy, "objective": objective, "learner": reward}
        if terminated or truncated:
            info["shadow_episode"] = self._end_episode(info, summary)
        return obs, reward, terminated, truncated, info

    def _episode_summary(self, info: Mapping[str, Any], step_summary: Mapping[str, Any]) -> dict[str, Any]:
        if "episode_summary" in info:
            return dict(info["episode_summary"])
        if "econ_episode" in info:
            return episode_summary(info["econ_episode"], self.meter, self.episode_index)
        raise ConfigError("<env>", "info.episode_summary", "no episode summary on the last step "
                          "(dishwashing: info['episode_summary']; MuJoCo: info['econ_episode'])")

    def _end_episode(self, info: Mapping[str, Any], step_summary: Mapping[str, Any]) -> dict[str, Any]:
        ep = self._episode_summary(info, step_summary)
        vector = self.vector.to_list()
        ep_terms = build_reward_terms(ep, self.economics, self.energy_term)
        weights = objective_weights(self.weights)
        record: dict[str, Any] = {
            "format": SHADOW_EPISODE_FORMAT,
            "task_id": self.task_id,
            "episode": self.episode_index,
            "steps": self.steps,
            "flipped": self.use_objective_reward,
            "objective_vector": vector,
            "reward_weights": self.weights.to_list(),
            "energy_term": self.energy_term,
            "energy_price_usd_per_kwh": energy_price_of(self.economics),
            "legacy_sum": self.legacy_sum,
            "objective_sum": self.objective_sum,
            "learner_sum": self.learner_sum,
            "term_totals": dict(self.term_sums),
            "term_totals_weighted": {k: w * self.term_sums[k] for k, w in weights.items()},
            "episode_terms": ep_terms,
            "episode_J": episode_j(ep, vector, self.economics, self.energy_term),
            "episode_objective": combine_reward(self.weights, ep_terms),
            "econ": {k: ep.get(k) for k in ECON_SUMMARY_KEYS if k in ep},
        }
        if self.constraints is not None:
            record["constraints"] = self.constraints.end_episode(ep)
        self.episode_index += 1
        return self.recorder.end_episode(record)
