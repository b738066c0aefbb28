"""A replay buffer that relabels Lagrangian-shaped rewards with the *current* multipliers.

SAC is off-policy: a transition collected ``k`` episodes ago is replayed long after the
multipliers it was shaped with have moved. With the shaped reward stored as is, the
penalty the critic learns lags the dual variable (most of the buffer carries old
lambdas), the dual variable overshoots while the learner catches up, and the policy ends
up more conservative than the limit asks for.

:class:`LagrangeRelabelReplayBuffer` stores, next to SB3's usual arrays, each transition's
**unshaped** reward ``r`` and the vector of its per-constraint signed-cost increments
``c_i = g_i(t) - g_i(t-1)`` (read from ``info[RELABEL_INFO_KEY]``, which
:class:`econmotor.rl.shadow.ShadowRewardWrapper` writes in ``lagrangian`` mode), and
returns, at sample time::

    reward = r - sum_i lambda_i * c_i          # lambda_i: the multipliers' values *now*

so every replayed transition carries the penalty of the current dual variable, and the
per-episode telescoping of :mod:`econmotor.rl.constraint_shaping` holds for every stored
episode with the current multipliers. The env-returned reward (what ``Monitor`` and the
shadow log see) is untouched and still stored in ``self.rewards``, the reward as shaped
at collection time.

Only the ``optimize_memory_usage=False`` layout is supported; any number of envs.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any, Protocol

import numpy as np
from gymnasium import spaces
from stable_baselines3.common.buffers import ReplayBuffer
from stable_baselines3.common.type_aliases import ReplayBufferSamples
from stable_baselines3.common.vec_env import VecNormalize

from econmotor.errors import ConfigError

#: the info key of a lagrangian-shaped step: ``{"reward_unshaped": float, "cost_increments": {name: float}}``
RELABEL_INFO_KEY = "lagrange_relabel"


class MultiplierSource(Protocol):
    """Anything with the current multiplier values by constraint name
    (:class:`econmotor.rl.lagrange.LagrangeMultipliers`)."""

    values: Mapping[str, float]


class LagrangeRelabelReplayBuffer(ReplayBuffer):
    """SB3 replay buffer whose sampled rewards are ``r_unshaped - sum_i lambda_i * c_i`` (module docstring).

    Pass it to SB3 as ``replay_buffer_class=LagrangeRelabelReplayBuffer,
    replay_buffer_kwargs={"multipliers": shaper.multipliers}``.

    Args:
        multipliers: the live multipliers (read at every ``sample``); their ``values``
            keys, in ``names`` order when the source has ``names``, fix the cost columns.
        names: the constraint names (default: ``multipliers.names`` or ``multipliers.values``' keys).
        (the rest): as :class:`stable_baselines3.common.buffers.ReplayBuffer`.
    """

    def __init__(self, buffer_size: int, observation_space: spaces.Space, action_space: spaces.Space,
                 device: Any = "auto", n_envs: int = 1, optimize_memory_usage: bool = False,
                 handle_timeout_termination: bool = True, *, multipliers: MultiplierSource,
                 names: Sequence[str] | None = None) -> None:
        if optimize_memory_usage:
            raise ValueError("LagrangeRelabelReplayBuffer supports only optimize_memory_usage=False "
                             "(it keeps next_observations; leave SAC's optimize_memory_usage off)")
        super().__init__(buffer_size, observation_space, action_space, device, n_envs=n_envs,
                         optimize_memory_usage=False, handle_timeout_termination=handle_timeout_termination)
        self.multipliers = multipliers
        if names is None:
            names = getattr(multipliers, "names", None) or tuple(multipliers.values)
        self.names = tuple(names)
        if not self.names:
            raise ValueError("LagrangeRelabelReplayBuffer needs at least one constraint name")
        missing = [n for n in self.names if n not in multipliers.values]
        if missing:
            raise ValueError(f"no multiplier for constraint(s) {missing}; "
                             f"multipliers have {sorted(multipliers.values)}")
        self.rewards_unshaped = np.zeros((self.buffer_size, self.n_envs), dtype=np.float64)
        self.cost_increments = np.zeros((self.buffer_size, self.n_envs, len(self.names)), dtype=np.float64)

    def add(self, obs: np.ndarray, next_obs: np.ndarray, action: np.ndarray, reward: np.ndarray,
            done: np.ndarray, infos: list[dict[str, Any]]) -> None:
        if len(infos) != self.n_envs:
            raise ValueError(f"expected {self.n_envs} info dicts (one per env), got {len(infos)}")
        unshaped = np.empty(self.n_envs, dtype=np.float64)
        costs = np.empty((self.n_envs, len(self.names)), dtype=np.float64)
        for env_idx, info in enumerate(infos):
            entry = info.get(RELABEL_INFO_KEY)
            if entry is None:
                raise ConfigError("<env>", f"info.{RELABEL_INFO_KEY}", "the relabelling replay buffer needs "
                                  "each step's unshaped reward and cost increments in info (ShadowRewardWrapper "
                                  "in lagrangian constraint mode writes them)")
            unshaped[env_idx] = float(entry["reward_unshaped"])
            increments = entry["cost_increments"]
            costs[env_idx] = [float(increments.get(name, 0.0)) for name in self.names]
        pos = self.pos  # super().add advances it
        super().add(obs, next_obs, action, reward, done, infos)
        self.rewards_unshaped[pos] = unshaped
        self.cost_increments[pos] = costs

    def lambdas(self) -> np.ndarray:
        """The current multipliers, in ``names`` order."""
        return np.array([float(self.multipliers.values[name]) for name in self.names], dtype=np.float64)

    def relabelled_rewards(self, batch_inds: np.ndarray, env_indices: np.ndarray) -> np.ndarray:
        """``r_unshaped - lambda . c`` of the given transitions with the current multipliers (float32)."""
        rewards = self.rewards_unshaped[batch_inds, env_indices] - self.cost_increments[batch_inds, env_indices] \
            @ self.lambdas()
        return rewards.astype(np.float32)

    def _get_samples(self, batch_inds: np.ndarray, env: VecNormalize | None = None) -> ReplayBufferSamples:
        env_indices = np.random.randint(0, high=self.n_envs, size=(len(batch_inds),))
        data = (
            self._normalize_obs(self.observations[batch_inds, env_indices, :], env),
            self.actions[batch_inds, env_indices, :],
            self._normalize_obs(self.next_observations[batch_inds, env_indices, :], env),
            (self.dones[batch_inds, env_indices] * (1 - self.timeouts[batch_inds, env_indices])).reshape(-1, 1),
            self._normalize_reward(self.relabelled_rewards(batch_inds, env_indices).reshape(-1, 1), env),
        )
        return ReplayBufferSamples(*tuple(map(self.to_torch, data)))


__all__ = ["RELABEL_INFO_KEY", "LagrangeRelabelReplayBuffer", "MultiplierSource"]
