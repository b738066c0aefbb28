"""The batched walker env (:class:`econmotor.couriers.walker_env.WalkerBatch`) as a Stable-Baselines3 ``VecEnv``.

SB3's convention: ``step`` returns ``(obs, rewards, dones, infos)`` for every env; an env whose episode
ended is reset in the same step (its ``obs`` row is the new episode's first observation), and the
ended episode's last observation is ``infos[i]["terminal_observation"]``, its raw metrics
``infos[i]["episode_metrics"]`` and SB3's ``infos[i]["episode"]`` (return ``r``, length ``l``, wall ``t``).
``TimeLimit.truncated`` marks an episode cut by its time limit rather than ended by the course or a fall.

Episodes are seeded ``seed, seed + 1, ...`` in the order they start. The reward is the step's change of
the economic overlay's potential (:func:`econmotor.economics.courier_formulas.overlay_potential` over the
episode's running sums, which count physics steps), so an episode's rewards sum to its ``J = sum_k
factor_k * metric_k`` over the overlay ``factors`` (key -> ``scale_k / reference_k``).
"""

from __future__ import annotations

import time
from collections.abc import Mapping
from typing import Any

import numpy as np
from gymnasium import spaces
from stable_baselines3.common.vec_env.base_vec_env import VecEnv

from econmotor.couriers.walker_env import WalkerBatch
from econmotor.economics import courier_formulas as cf
from econmotor.economics.termination import TerminationReason


class WalkerVecEnv(VecEnv):
    """``batch.n`` walkers as one SB3 ``VecEnv`` (module docstring)."""

    def __init__(self, batch: WalkerBatch, factors: Mapping[str, float], seed: int = 0) -> None:
        card = batch.card
        obs_space = spaces.Box(-np.inf, np.inf, (card.obs_dim,), np.float32)
        act_space = spaces.Box(-card.action_clip, card.action_clip, (card.num_dofs,), np.float32)
        self.render_mode = None
        super().__init__(batch.n, obs_space, act_space)
        self.batch, self.next_seed = batch, int(seed)
        self.coefficients = cf.overlay_coefficients(factors, card.physics_dt_s)  # the meter's steps
        self.slots = np.arange(batch.n)
        self.returns, self.started = np.zeros(batch.n), np.zeros(batch.n)
        self.potential = np.zeros(batch.n)
        self._actions: np.ndarray | None = None
        self._obs = np.zeros((batch.n, card.obs_dim), np.float32)

    def _start(self, slot: int) -> None:
        self.batch.start(slot, self.next_seed, self.next_seed)
        self.next_seed += 1
        self.returns[slot], self.started[slot], self.potential[slot] = 0.0, time.monotonic(), 0.0

    def _potential(self) -> np.ndarray:
        return np.asarray(cf.overlay_potential(self.batch.sums, self.coefficients, np), dtype=np.float64)

    def reset(self) -> np.ndarray:
        for slot in self.slots:
            self._start(int(slot))
        self._obs = self.batch.observe(self.slots)
        return self._obs

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = np.asarray(actions)

    def step_wait(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[dict[str, Any]]]:
        done = self.batch.act(self.slots, self._actions)
        potential = self._potential()
        rewards = potential - self.potential
        self.potential = potential
        self.returns += rewards
        infos: list[dict[str, Any]] = [{} for _ in self.slots]
        for slot in np.flatnonzero(done):
            terminal = self.batch.observation(np.array([slot]))[0]
            steps = int(self.batch.steps[slot])
            metrics = self.batch.finish(int(slot))
            infos[slot] = {"terminal_observation": terminal, "episode_metrics": metrics,
                           "TimeLimit.truncated": metrics["termination_reason"] == TerminationReason.MAX_STEPS,
                           "episode": {"r": float(self.returns[slot]), "l": steps,
                                       "t": round(time.monotonic() - self.started[slot], 6)}}
            self._start(int(slot))
        self._obs = self.batch.observe(self.slots)
        return self._obs, rewards.astype(np.float32), done, infos

    def close(self) -> None:
        self.batch.close()

    def get_attr(self, attr_name: str, indices: Any = None) -> list[Any]:
        return [getattr(self, attr_name) for _ in self._indices(indices)]

    def set_attr(self, attr_name: str, value: Any, indices: Any = None) -> None:
        setattr(self, attr_name, value)

    def env_method(self, method_name: str, *args: Any, indices: Any = None, **kwargs: Any) -> list[Any]:
        return [getattr(self, method_name)(*args, **kwargs) for _ in self._indices(indices)]

    def env_is_wrapped(self, wrapper_class: type, indices: Any = None) -> list[bool]:
        return [False for _ in self._indices(indices)]

    def seed(self, seed: int | None = None) -> list[int | None]:
        if seed is not None:
            self.next_seed = int(seed)
        return [seed for _ in self.slots]

    def _indices(self, indices: Any) -> list[int]:
        if indices is None:
            return list(range(self.num_envs))
        return [indices] if isinstance(indices, int) else list(indices)
