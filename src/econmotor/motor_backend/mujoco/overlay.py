"""EconomicOverlayWrapper: the task's reward plus the compiled economic overlay.

Reward at step t::

    r_t = r_task_t * keep_task_reward + sum_k scale_k * term_k(t)

Each term is the change of the *running* episode metric of its key, read from the
metering wrapper's :class:`~econmotor.motor_backend.mujoco.metering.EpisodeTally`::

    term_k(t) = m_k(t) - m_k(t-1),   m_k(0) = 0

so the sum over an episode telescopes to ``m_k(T)``, the episode's metric of that key
(the invariant every backend keeps: ``sum_t term_k(t) == episode metric k``). Keys:

- ``mpl_per_hour``: good units per hour, ``units / hours`` (= EconomicMeter ``mpl_units_per_hour``)
- ``error_rate``: ``errors / (units + errors)``
- ``energy_kwh``: electrical energy, kWh
- ``risk_score`` / ``novelty_score``: means over steps
- ``pose_tracking``: sum of per-step pose similarity (only with motion clips)

At an episode's end ``info["overlay_terms"] = {key: {"raw": sum term, "weighted": scale * sum}}``
and ``info["overlay_return"]`` (the overlay's part of the return) are added.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import gymnasium as gym

from econmotor.errors import ConfigError
from econmotor.motor_backend.mujoco.metering import EconomicMeteringWrapper, EpisodeTally, find_wrapper

#: overlay key -> the EpisodeTally method giving its running episode metric.
TERM_METRICS: dict[str, str] = {
    "mpl_per_hour": "mpl_per_hour",
    "error_rate": "error_rate",
    "energy_kwh": "energy_kwh",
    "risk_score": "risk_score",
    "novelty_score": "novelty_score",
    "pose_tracking": "pose_tracking",
}


def episode_metric(raw_episode: Mapping[str, Any], key: str) -> float:
    """The episode metric of overlay ``key`` from an episode's raw metrics (the invariant's right side)."""
    units, errors = float(raw_episode["units_completed"]), float(raw_episode["errors"])
    if key == "mpl_per_hour":
        hours = float(raw_episode["episode_length_s"]) / 3600.0
        return units / hours if hours > 0 else 0.0
    if key == "error_rate":
        return errors / (units + errors) if units + errors > 0 else 0.0
    if key == "energy_kwh":
        return float(raw_episode["energy_wh"]) / 1000.0
    return float(raw_episode.get(key, 0.0))


class EconomicOverlayWrapper(gym.Wrapper):
    """Add ``sum_k scale_k * term_k`` to (or in place of) the task reward (see module doc).

    Args:
        env: an env with an :class:`EconomicMeteringWrapper` in its wrapper chain.
        scales: overlay key -> signed scale (a ``CompiledRewardOverlay`` or a plain mapping).
        keep_task_reward: keep the env's own reward (True) or use the overlay alone (False).
    """

    def __init__(self, env: gym.Env, scales: Mapping[str, float], keep_task_reward: bool = True) -> None:
        super().__init__(env)
        meter = find_wrapper(env, EconomicMeteringWrapper)
        if meter is None:
            raise ConfigError("EconomicOverlayWrapper", "env", "needs an EconomicMeteringWrapper inside it")
        unknown = [k for k in scales if k not in TERM_METRICS]
        if unknown:
            raise ConfigError("objective", f"extra_weights.{unknown[0]}",
                              "the mujoco backend has no reward term of this name", list(TERM_METRICS))
        self.scales = {k: float(v) for k, v in scales.items()}
        self.keep_task_reward = bool(keep_task_reward)
        self._tally: EpisodeTally = meter.tally
        self._fns = [(k, s, getattr(EpisodeTally, TERM_METRICS[k])) for k, s in self.scales.items()]
        self._prev = {k: 0.0 for k in self.scales}
        self._sums = {k: 0.0 for k in self.scales}

    def reset(self, **kwargs: Any):
        for k in self.scales:
            self._prev[k] = self._sums[k] = 0.0
        return self.env.reset(**kwargs)

    def step(self, action):
        obs, reward, terminated, truncated, info = self.env.step(action)
        total = float(reward) if self.keep_task_reward else 0.0
        tally, prev, sums = self._tally, self._prev, self._sums
        for key, scale, fn in self._fns:
            value = fn(tally)
            term = value - prev[key]
            prev[key] = value
            sums[key] += term
            total += scale * term
        if terminated or truncated:
            info["overlay_terms"] = {k: {"raw": sums[k], "weighted": self.scales[k] * sums[k]} for k in sums}
            info["overlay_return"] = sum(self.scales[k] * sums[k] for k in sums)
        return obs, total, terminated, truncated, info
