"""The economic overlay of the couriers (mujoco and mjx): the task's reward plus the compiled objective.

Reward at step t::

    r_t = r_task_t * keep_task_reward + sum_k scale_k * term_k(t)

Each term is the change of the *running* episode metric of its key (the episode's metering
sums, :func:`~econmotor.economics.courier_formulas.running_metrics`)::

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
``J(t) = sum_k (scale_k / ref_k) * m_k(t)`` (the same sum regrouped,
:func:`~econmotor.economics.courier_formulas.overlay_potential`): in the mujoco backend's
metering wrapper (``mujoco/metering.py``) and in the mjx backend's jitted step (``mjx/env.py``).
At an episode's end the mujoco backend adds ``info["overlay_terms"] = {key: {"raw": m_k(T),
"weighted": scale_k * m_k(T) / ref_k}}`` (``m_k(T)`` is the term's episode sum, telescoped) and
``info["overlay_return"]`` (the overlay's part of the return, ``J(T)``). This module holds the
overlay's keys, its checks and references.
"""

from __future__ import annotations

from collections.abc import Mapping

from econmotor.economics.courier_formulas import RUNNING_METRIC_KEYS, overlay_factors
from econmotor.errors import ConfigError

#: overlay keys the couriers can weight (each a running episode metric of the same name).
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


def overlay_term_factors(scales: Mapping[str, float], references: Mapping[str, float] | None = None,
                         terms: tuple[str, ...] = TERM_METRICS, backend: str = "mujoco") -> dict[str, float]:
    """Check an overlay's ``scales`` (keys: ``terms``) and ``references`` (> 0); ``scale_k / ref_k``."""
    unknown = [k for k in scales if k not in terms]
    if unknown:
        raise ConfigError("objective", f"extra_weights.{unknown[0]}",
                          f"the {backend} backend has no reward term of this name", list(terms))
    refs = dict(references or {})
    bad = [k for k, v in refs.items() if not v > 0]
    if bad:
        raise ConfigError("EconomicMeteringWrapper", f"references.{bad[0]}", "must be > 0")
    return overlay_factors(scales, refs)
