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

from econmotor.economics import courier_formulas
from econmotor.economics.courier_formulas import (
    PY,
    RUNNING_METRIC_KEYS,
    overlay_factors,
    overlay_potential,
    potential_coefficients,
)
from econmotor.errors import ConfigError
from econmotor.motor_backend.mujoco.metering import EconomicMeteringWrapper, EpisodeTally, find_wrapper

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


#: the episode metric of an overlay key from an episode's raw metrics (the invariant's right side).
episode_metric = courier_formulas.episode_metric


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
        self.factors = overlay_factors(self.scales, refs)
        self.keep_task_reward = bool(keep_task_reward)
        self._tally: EpisodeTally = meter.tally
        self._keys = list(self.factors)
        # sum_k factor_k * term_k(t) = J(t) - J(t-1) with J(t) = sum_k factor_k * m_k(t), so one
        # scalar per step (overlay_potential: J's coefficients on the tally's running sums)
        self._coef = potential_coefficients(self.factors, meter.dt_s)
        self._metric_index = [RUNNING_METRIC_KEYS.index(k) for k in self._keys]
        self._prev_j = 0.0  # J at the previous step (J(0) = 0: every running metric is 0 after reset)

    def reset(self, **kwargs: Any):
        self._prev_j = 0.0
        return self.env.reset(**kwargs)

    def step(self, action):
        obs, reward, terminated, truncated, info = self.env.step(action)
        t = self._tally
        j = overlay_potential(self._coef, t, PY)  # reads t.novelty_sum (counting queued visits) only if weighted
        overlay_r = j - self._prev_j
        self._prev_j = j
        total = float(reward) + overlay_r if self.keep_task_reward else overlay_r
        if terminated or truncated:  # each term's episode sum telescopes to the episode's metric m_k(T)
            metrics, factors = t.running_metrics(), self.factors
            info["overlay_terms"] = {k: {"raw": metrics[i], "weighted": factors[k] * metrics[i]}
                                     for k, i in zip(self._keys, self._metric_index, strict=True)}
            info["overlay_return"] = j  # J(T) = sum_k factor_k * m_k(T), the weighted terms' sum
        return obs, total, terminated, truncated, info
