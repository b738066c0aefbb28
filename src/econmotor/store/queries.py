"""Row building and query filters shared by the registry's read and write methods."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

from sqlalchemy import distinct, exists, func, select

from econmotor.errors import RegistryError
from econmotor.store.models import EPISODE_COLUMNS, RUN_STATUSES, EpisodeRow, RunDatapackRow, RunRow


def check_status(status: str) -> None:
    if status not in RUN_STATUSES:
        raise RegistryError(f"run status must be one of {RUN_STATUSES}, got {status!r}")


def filter_runs(stmt: Any, task_id: str | None, backend: str | None, datapacks: Sequence[str] | str | None,
            objective: str | None, kind: str | None, status: str | None) -> Any:
    if task_id:
        stmt = stmt.where(RunRow.task_id == task_id)
    if backend:
        stmt = stmt.where(RunRow.backend == backend)
    if objective:
        stmt = stmt.where(RunRow.objective_name == objective)
    if kind:
        stmt = stmt.where(RunRow.kind == kind)
    if status:
        stmt = stmt.where(RunRow.status == status)
    if datapacks is not None:
        ids = [datapacks] if isinstance(datapacks, str) else list(dict.fromkeys(datapacks))
        if not ids:
            stmt = stmt.where(~exists().where(RunDatapackRow.run_id == RunRow.id))
        else:
            having = (select(RunDatapackRow.run_id).where(RunDatapackRow.datapack_id.in_(ids))
                      .group_by(RunDatapackRow.run_id)
                      .having(func.count(distinct(RunDatapackRow.datapack_id)) == len(ids)))
            stmt = stmt.where(RunRow.id.in_(having))
    return stmt


def episode_row(run_id: int, summary: Mapping[str, Any], index: int) -> EpisodeRow:
    columns = {}
    for key in EPISODE_COLUMNS:
        value = summary.get(key)
        try:
            value = float(value) if value is not None else None
        except (TypeError, ValueError):
            value = None
        columns[key] = None if value is None or math.isnan(value) else value
    return EpisodeRow(run_id=run_id, episode_index=int(summary.get("episode_index", index)),
                      termination_reason=str(summary.get("termination_reason", "max_steps")),
                      summary=dict(summary), **columns)
