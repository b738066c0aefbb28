"""Frozen records the registry returns (detached from the database session)."""

from __future__ import annotations

import datetime as dt
from dataclasses import dataclass, field
from typing import Any

from econmotor.store.models import ReportRow, RunRow


@dataclass(frozen=True)
class RunRecord:
    """One recorded run. Metric dicts use the raw and econ metric keys of ``econmotor.economics``."""

    id: int
    kind: str
    task_id: str
    backend: str
    status: str
    objective_name: str
    objective: dict[str, Any]
    datapack_ids: tuple[str, ...]
    config: dict[str, Any]
    seed: int | None
    num_envs: int | None
    max_steps: int | None
    policy_path: str | None
    raw_metrics: dict[str, Any]
    econ_metrics: dict[str, Any]
    training_curve: list[dict[str, Any]]
    artifacts: dict[str, Any]
    notes: str
    error: str | None
    parent_run_id: int | None
    robot_id: str | None
    created_at: dt.datetime | None
    finished_at: dt.datetime | None


@dataclass(frozen=True)
class EpisodeRecord:
    """One evaluation episode with the run facts a solver filters on.

    ``summary`` is the per-episode summary as the backend produced it (raw metrics,
    econ metrics and the RewardBuilder names ``mpl_episode``, ``error_rate_episode``,
    ``energy_Wh``, ...). ``record["key"]`` reads the summary.
    """

    run_id: int
    episode_index: int
    task_id: str
    backend: str
    run_kind: str
    objective_name: str
    datapack_ids: tuple[str, ...]
    seed: int | None
    termination_reason: str
    summary: dict[str, Any] = field(default_factory=dict)

    def __getitem__(self, key: str) -> Any:
        return self.summary[key]

    def get(self, key: str, default: Any = None) -> Any:
        return self.summary.get(key, default)


@dataclass(frozen=True)
class ReportRecord:
    id: int
    task_id: str
    train_run_id: int | None
    eval_run_id: int | None
    document: dict[str, Any]
    files: dict[str, str]
    created_at: dt.datetime | None


def _utc(value: dt.datetime | None) -> dt.datetime | None:
    """SQLite hands back naive datetimes; every timestamp econmotor writes is UTC."""
    return value.replace(tzinfo=dt.UTC) if value is not None and value.tzinfo is None else value


def run_record(row: RunRow) -> RunRecord:
    return RunRecord(
        id=row.id, kind=row.kind, task_id=row.task_id, backend=row.backend, status=row.status,
        objective_name=row.objective_name, objective=dict(row.objective or {}),
        datapack_ids=tuple(row.datapack_ids or ()), config=dict(row.config or {}), seed=row.seed,
        num_envs=row.num_envs, max_steps=row.max_steps, policy_path=row.policy_path,
        raw_metrics=dict(row.raw_metrics or {}), econ_metrics=dict(row.econ_metrics or {}),
        training_curve=list(row.training_curve or []), artifacts=dict(row.artifacts or {}),
        notes=row.notes or "", error=row.error, parent_run_id=row.parent_run_id, robot_id=row.robot_id,
        created_at=_utc(row.created_at), finished_at=_utc(row.finished_at),
    )


def episode_record(ep: Any, run: RunRow) -> EpisodeRecord:
    """``ep``: an EpisodeRow or a row with its run_id, episode_index, termination_reason, summary."""
    return EpisodeRecord(
        run_id=ep.run_id, episode_index=ep.episode_index, task_id=run.task_id, backend=run.backend,
        run_kind=run.kind, objective_name=run.objective_name, datapack_ids=tuple(run.datapack_ids or ()),
        seed=run.seed, termination_reason=ep.termination_reason, summary=dict(ep.summary or {}),
    )


def report_record(row: ReportRow) -> ReportRecord:
    return ReportRecord(row.id, row.task_id, row.train_run_id, row.eval_run_id, dict(row.document or {}),
                        dict(row.files or {}), _utc(row.created_at))
