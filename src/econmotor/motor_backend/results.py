"""What an evaluation and a training return: raw metrics per episode, their aggregate, provenance.

Per-episode raw metrics use the meter's keys (``units_completed``, ``units_attempted``,
``errors``, ``episode_length_s``, ``energy_wh``, ``risk_score``, ``novelty_score``)
plus ``return`` and ``termination_reason`` (one of :class:`econmotor.economics.termination.TerminationReason`);
:func:`summarize_episodes` turns them into the aggregate raw metrics, the econ metrics and
per-episode summaries that also carry the RewardBuilder names (``mpl_episode``,
``error_rate_episode``, ``energy_Wh``, ``energy_Wh_per_unit``, ``wage_parity``).
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from econmotor.config.task_economics import TaskEconomics
from econmotor.economics.courier_formulas import rate_length_s
from econmotor.economics.meter import EconomicMeter
from econmotor.economics.termination import TerminationReason
from econmotor.motor_backend.run_dir import EVALUATION_FILE

#: raw per-episode keys that are summed when episodes are aggregated.
ADDITIVE_RAW_KEYS = ("units_completed", "units_attempted", "errors", "episode_length_s", "energy_wh")
#: raw per-episode keys that are averaged.
MEAN_RAW_KEYS = ("risk_score", "novelty_score", "return", "length_steps")


@dataclass(frozen=True)
class MotorTrainingResult:
    """What ``train_policy`` returns.

    Attributes:
        policy_id: path of the saved policy; pass it to ``evaluate_policy`` / ``deploy_policy_handle``.
        task_id: the task trained on.
        backend: the backend's factory name.
        raw_metrics: aggregate raw metrics of the post-training evaluation episodes.
        econ_metrics: ``EconomicMeter.summarize(raw_metrics)``.
        episodes: one summary per evaluation episode (see :func:`summarize_episodes`).
        training_curve: ``[{"timesteps": int, "mean_return": float}, ...]`` during training.
        config: everything needed to reproduce the run (seed, objective, datapacks, hyperparameters).
        artifacts: named output files (policy, TensorBoard dir, ONNX, ...).
    """

    policy_id: str
    task_id: str
    backend: str
    raw_metrics: dict[str, float]
    econ_metrics: dict[str, float]
    episodes: list[dict[str, Any]] = field(default_factory=list)
    training_curve: list[dict[str, float]] = field(default_factory=list)
    config: dict[str, Any] = field(default_factory=dict)
    artifacts: dict[str, str] = field(default_factory=dict)


#: the key under which an evaluation's :class:`EvalProvenance` also travels in its ``config`` (and in
#: ``evaluation.json`` and the registry's run config): a result rebuilt from its config keeps it.
PROVENANCE_KEY = "provenance"


@dataclass(frozen=True)
class EvalProvenance:
    """How an evaluation's figures were made: what a report and ``compare`` say beside the economics.

    Every backend fills it in ``evaluate_policy``; what a backend does not measure stays None.

    Attributes:
        evaluator: the evaluator's short name ("sim2sim", "eval_agent", "mujoco", "mjx", "analytic").
        figures_from: where the figures come from, in words (simulator, model, policy format).
        imported: the policy was trained elsewhere (nothing was trained here).
        commanded_speed_m_per_s: the course's commanded speed, m/s (None: no commanded course).
        achieved_speed_m_per_s: the speed achieved while walking, m/s, weighted by walking time over the
            episodes (None: no course).
        mean_power_w: mean electrical power over the episodes, W (None: not metered).
        mean_mech_power_w: the mechanical power behind it, W (None: not metered).
        mean_heat_power_w: the joint motors' winding heat in it, W (None: no motor model).
        stated_runtime_h: the maker's runtime per charge, h, from the robot's card (None: not stated);
        stated_runtime: what the maker states it for (e.g. "continuous operation"); ``stated_runtime_source``:
            where the maker states it.
    """

    evaluator: str = "unknown"
    figures_from: str = "not stated by the backend"
    imported: bool = False
    commanded_speed_m_per_s: float | None = None
    achieved_speed_m_per_s: float | None = None
    mean_power_w: float | None = None
    mean_mech_power_w: float | None = None
    mean_heat_power_w: float | None = None
    stated_runtime_h: float | None = None
    stated_runtime: str | None = None
    stated_runtime_source: str | None = None

    def to_dict(self) -> dict[str, Any]:
        """The fields as a JSON-ready dict (what the registry and ``evaluation.json`` record)."""
        return dict(self.__dict__)

    @classmethod
    def from_dict(cls, values: Mapping[str, Any]) -> EvalProvenance:
        """The provenance :meth:`to_dict` recorded (unknown keys ignored)."""
        return cls(**{k: v for k, v in values.items() if k in cls.__dataclass_fields__})


@dataclass(frozen=True)
class MotorEvalResult:
    """What ``evaluate_policy`` returns (fields as in :class:`MotorTrainingResult`), plus ``provenance``
    (:class:`EvalProvenance`: which evaluator made the figures, speeds, power).

    ``config`` always carries the provenance too, under :data:`PROVENANCE_KEY`; a result built without
    ``provenance`` from a config that records one (e.g. a sequential evaluation rebuilding its result from
    the episodes it kept) takes it from there.
    """

    policy_id: str
    task_id: str
    backend: str
    raw_metrics: dict[str, float]
    econ_metrics: dict[str, float]
    episodes: list[dict[str, Any]] = field(default_factory=list)
    config: dict[str, Any] = field(default_factory=dict)
    provenance: EvalProvenance = field(default_factory=EvalProvenance)

    def __post_init__(self) -> None:
        recorded = self.config.get(PROVENANCE_KEY)
        if self.provenance == EvalProvenance() and recorded:
            object.__setattr__(self, "provenance", EvalProvenance.from_dict(recorded))
        object.__setattr__(self, "config", {**self.config, PROVENANCE_KEY: self.provenance.to_dict()})


def walking_speed_m_per_s(raw_episodes: Sequence[Mapping[str, Any]]) -> float | None:
    """The speed achieved while walking over episodes that walk a course (each with
    ``achieved_speed_m_per_s`` and ``walking_s``): ``sum(v_i * t_i) / sum(t_i)`` m/s, 0 when no episode
    walked; None when the episodes carry no speed (no course)."""
    if not raw_episodes or any("achieved_speed_m_per_s" not in e or "walking_s" not in e for e in raw_episodes):
        return None
    walking_s = sum(float(e["walking_s"]) for e in raw_episodes)
    return sum(float(e["achieved_speed_m_per_s"]) * float(e["walking_s"]) for e in raw_episodes) / walking_s \
        if walking_s > 0 else 0.0


def mean_power_w(raw_metrics: Mapping[str, Any]) -> float | None:
    """Mean electrical power of aggregated episodes, ``energy_wh / (episode_length_s / 3600)`` W (None:
    no energy metered; 0 for no time)."""
    if raw_metrics.get("energy_wh") is None:
        return None
    hours = float(raw_metrics.get("episode_length_s") or 0.0) / 3600.0
    return float(raw_metrics["energy_wh"]) / hours if hours > 0 else 0.0


def aggregate_raw(raw_episodes: Sequence[Mapping[str, Any]]) -> dict[str, float]:
    """Sum the additive keys and average the rest over episodes; adds ``num_episodes``."""
    out: dict[str, float] = {"num_episodes": float(len(raw_episodes))}
    if not raw_episodes:
        return out
    for key in ADDITIVE_RAW_KEYS:
        values = [float(ep[key]) for ep in raw_episodes if ep.get(key) is not None]
        if values:
            out[key] = float(np.sum(values))
    for key in MEAN_RAW_KEYS:
        values = [float(ep[key]) for ep in raw_episodes if ep.get(key) is not None]
        if values:
            out[key] = float(np.mean(values))
    return out


def episode_summary(raw_episode: Mapping[str, Any], meter: EconomicMeter, index: int) -> dict[str, Any]:
    """One episode's raw metrics plus its econ metrics and the RewardBuilder field names."""
    econ = meter.summarize(raw_episode, source=f"episode {index}")
    summary: dict[str, Any] = {"episode_index": index, **dict(raw_episode), **econ}
    mpl = econ["mpl_units_per_hour"]
    limit_s = raw_episode.get("episode_limit_s")
    if limit_s is not None and float(raw_episode.get("errors") or 0.0) > 0:
        # a fall: the episode's J rate is over its whole time limit (courier_formulas.rate_length_s)
        seconds = float(rate_length_s(float(raw_episode["episode_length_s"]), float(limit_s), True, np))
        mpl = meter.summarize({**raw_episode, "episode_length_s": seconds},
                              source=f"episode {index}")["mpl_units_per_hour"]
    summary.update(
        mpl_episode=mpl,
        error_rate_episode=econ["error_rate"],
        energy_Wh=econ["energy_wh"],
        energy_Wh_per_unit=econ["energy_wh_per_unit"],
    )
    summary.setdefault("termination_reason", TerminationReason.MAX_STEPS.value)
    return summary


def summarize_episodes(
    raw_episodes: Sequence[Mapping[str, Any]], economics: TaskEconomics
) -> tuple[dict[str, float], dict[str, float], list[dict[str, Any]]]:
    """Return (aggregate raw metrics, econ metrics, per-episode summaries) of evaluation episodes.

    Aggregate econ metrics are ratios of sums (total good units / total hours, ...),
    not means of per-episode ratios.
    """
    meter = EconomicMeter(economics)
    raw = aggregate_raw(raw_episodes)
    econ = meter.summarize(raw) if raw_episodes else {}
    return raw, econ, [episode_summary(ep, meter, i) for i, ep in enumerate(raw_episodes)]


def evaluation_result(backend: str, policy_id: str, task_id: str, raw_episodes: Sequence[Mapping[str, Any]],
                      economics: TaskEconomics, config: Mapping[str, Any],
                      output_dir: str | Path | None = None,
                      provenance: EvalProvenance | None = None) -> MotorEvalResult:
    """The :class:`MotorEvalResult` of evaluation episodes (see :func:`summarize_episodes`); with
    ``output_dir``, also written there as ``evaluation.json`` (metrics, episodes, config with the
    provenance). ``provenance``: None keeps the one ``config`` records, if any."""
    raw, econ, episodes = summarize_episodes(raw_episodes, economics)
    result = MotorEvalResult(policy_id=str(policy_id), task_id=task_id, backend=backend, raw_metrics=raw,
                             econ_metrics=econ, episodes=episodes, config=dict(config),
                             provenance=provenance or EvalProvenance())
    if output_dir is not None:
        out = Path(output_dir)
        out.mkdir(parents=True, exist_ok=True)
        (out / EVALUATION_FILE).write_text(json.dumps(
            {"raw_metrics": raw, "econ_metrics": econ, "episodes": episodes, "config": result.config},
            indent=2, default=str), encoding="utf-8")
    return result
