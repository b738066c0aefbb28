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

With per-key references ``ref_k`` (``overlay_normalization: human_baseline``, see
:func:`human_baseline_references`) the reward uses ``scale_k * term_k(t) / ref_k``: a weight
of 1 is then "one human baseline's worth" of that metric, so an objective's weights compare
like with like (throughput in legs/h is ~100x the task reward's scale, the error rate ~1/100).

Per step the overlay reward is computed as one difference, ``J(t) - J(t-1)`` with
``J(t) = sum_k (scale_k / ref_k) * m_k(t)`` (the same sum regrouped). At an episode's end
``info["overlay_terms"] = {key: {"raw": m_k(T), "weighted": scale_k * m_k(T) / ref_k}}`` (``m_k(T)``
is the term's episode sum, telescoped) and ``info["overlay_return"]`` (the overlay's part of the
return, ``J(T)``) are added.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import gymnasium as gym

from econmotor.errors import ConfigError
from econmotor.motor_backend.mujoco.metering import (
    RUNNING_METRIC_KEYS,
    EconomicMeteringWrapper,
    EpisodeTally,
    find_wrapper,
)

#: overlay keys this backend can weight (each an EpisodeTally running metric of the same name).
TERM_METRICS: tuple[str, ...] = RUNNING_METRIC_KEYS


def human_baseline_references(mp_human_units_per_hour: float, error_rate_human: float, idle_power_w: float,
                              max_episode_s: float) -> dict[str, float]:
    """Per-key references for ``overlay_normalization: human_baseline``.

    ``mpl_per_hour``: the human's legs per hour ``MP_h``; ``error_rate``: the human's error rate
    ``e_h``; ``energy_kwh``: ``idle_power_w * max_episode_s / 3.6e6``, the kWh the robot draws
    standing idle for a whole episode; ``risk_score``, ``novelty_score``, ``pose_tracking``: 1.
    """
    return {
        "mpl_per_hour": mp_human_units_per_hour if mp_human_units_per_hour > 0 else 1.0,
        "error_rate": error_rate_human if error_rate_human > 0 else 1.0,
        "energy_kwh": idle_power_w * max_episode_s / 3.6e6 if idle_power_w * max_episode_s > 0 else 1.0,
        "risk_score": 1.0, "novelty_score": 1.0, "pose_tracking": 1.0,
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
        references: overlay key -> positive divisor of its term (missing keys: 1).
    """

    def __init__(self, env: gym.Env, scales: Mapping[str, float], keep_task_reward: bool = True,
                 references: Mapping[str, float] | None = None) -> None:
        super().__init__(env)
        meter = find_wrapper(env, EconomicMeteringWrapper)
        if meter is None:
            raise ConfigError("EconomicOverlayWrapper", "env", "needs an EconomicMeteringWrapper inside it")
        unknown = [k for k in scales if k not in TERM_METRICS]
        if unknown:
            raise ConfigError("objective", f"extra_weights.{unknown[0]}",
                              "the mujoco backend has no reward term of this name", list(TERM_METRICS))
        refs = dict(references or {})
        bad = [k for k, v in refs.items() if not v > 0]
        if bad:
            raise ConfigError("EconomicOverlayWrapper", f"references.{bad[0]}", "must be > 0")
        self.scales = {k: float(v) for k, v in scales.items()}
        #: the per-step multiplier of each term: scale / reference
        self.factors = {k: self.scales[k] / float(refs.get(k, 1.0)) for k in self.scales}
        self.keep_task_reward = bool(keep_task_reward)
        self._tally: EpisodeTally = meter.tally
        self._keys = list(self.factors)
        # sum_k factor_k * term_k(t) = J(t) - J(t-1) with J(t) = sum_k factor_k * m_k(t), so one
        # scalar per step; J's coefficients on the tally's running sums (m_k as in EpisodeTally):
        f = self.factors
        self._coef = (
            f.get("mpl_per_hour", 0.0) * 3600.0 / meter.dt_s,  # x units / steps
            f.get("risk_score", 0.0),  # x risk_sum / steps
            f.get("novelty_score", 0.0),  # x novelty_sum / steps
            f.get("error_rate", 0.0),  # x errors / (units + errors)
            f.get("energy_kwh", 0.0) / 1000.0,  # x energy_wh
            f.get("pose_tracking", 0.0),  # x pose_sum
        )
        self._metric_index = [RUNNING_METRIC_KEYS.index(k) for k in self._keys]
        self._prev_j = 0.0  # J at the previous step (J(0) = 0: every running metric is 0 after reset)

    def reset(self, **kwargs: Any):
        self._prev_j = 0.0
        return self.env.reset(**kwargs)

    def step(self, action):
        obs, reward, terminated, truncated, info = self.env.step(action)
        t = self._tally
        c_units, c_risk, c_novelty, c_error, c_energy, c_pose = self._coef
        steps = t.steps
        per_step = c_units * t.units + c_risk * t.risk_sum
        if c_novelty:  # reading novelty_sum counts the meter's queued visits
            per_step += c_novelty * t.novelty_sum
        j = (per_step / steps if steps else 0.0) + c_energy * t.energy_wh + c_pose * t.pose_sum
        errors = t.errors
        if errors and c_error:
            j += c_error * errors / (t.units + errors)
        overlay_r = j - self._prev_j
        self._prev_j = j
        total = float(reward) + overlay_r if self.keep_task_reward else overlay_r
        if terminated or truncated:  # each term's episode sum telescopes to the episode's metric m_k(T)
            metrics = t.running_metrics()
            raw = {k: metrics[i] for k, i in zip(self._keys, self._metric_index, strict=True)}
            info["overlay_terms"] = {k: {"raw": raw[k], "weighted": self.factors[k] * raw[k]} for k in self._keys}
            info["overlay_return"] = j  # J(T) = sum_k factor_k * m_k(T), the weighted terms' sum
        return obs, total, terminated, truncated, info
