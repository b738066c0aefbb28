"""The registry's queries: datapacks, runs, episodes (as records or numpy columns) and reports.

:class:`RegistryReads` reads what :class:`econmotor.store.Registry` wrote, each query one
transaction. Filters: ``datapacks`` keeps runs that used every listed id (``[]`` keeps runs that
used none); ``objective`` matches the objective name; ``episodes`` and ``episode_arrays`` read
completed runs by default. Usage::

    reg.runs(task_id="dishwashing", status="completed")            # -> [RunRecord]
    reg.episodes(task_id="dishwashing", backend="dishwashing",
                 datapacks=["dr_v1"], objective="throughput")      # -> [EpisodeRecord]
    reg.episode_arrays(["mpl_units_per_hour", "error_rate"], task_id="dishwashing")  # numpy
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import Any

import numpy as np
from sqlalchemy import select

from econmotor.config.datapacks import DatapackConfig, parse_datapack
from econmotor.errors import UnknownNameError
from econmotor.store.database import RegistryDatabase
from econmotor.store.models import EPISODE_COLUMNS, DatapackRow, EpisodeRow, ReportRow, RunRow
from econmotor.store.queries import filter_runs
from econmotor.store.records import (
    EpisodeRecord,
    ReportRecord,
    RunRecord,
    episode_record,
    report_record,
    run_record,
)


class RegistryReads(RegistryDatabase):
    """Queries of an open registry database (see the module docstring)."""

    # ------------------------------------------------------------------ datapacks
    def known_datapack_ids(self) -> list[str]:
        with self._read() as s:
            return sorted(s.scalars(select(DatapackRow.datapack_id)))

    def datapack_configs(self, ids: Sequence[str]) -> list[DatapackConfig]:
        """Registered datapacks by id, in order; an unknown id lists the known ones."""
        with self._read() as s:
            rows = {r.datapack_id: r for r in s.scalars(select(DatapackRow))}
        out = []
        for pack_id in ids:
            if pack_id not in rows:
                raise UnknownNameError("datapack id", pack_id, rows)
            out.append(parse_datapack(rows[pack_id].config, f"registry:{pack_id}"))
        return out

    # ------------------------------------------------------------------ runs
    def run(self, run_id: int) -> RunRecord:
        with self._read() as s:
            return run_record(self._get_run(s, run_id))

    def runs(self, task_id: str | None = None, backend: str | None = None,
             datapacks: Sequence[str] | str | None = None, objective: str | None = None,
             kind: str | None = None, status: str | None = None) -> list[RunRecord]:
        """Runs matching every given filter, oldest first."""
        stmt = filter_runs(select(RunRow), task_id, backend, datapacks, objective, kind, status).order_by(RunRow.id)
        with self._read() as s:
            return [run_record(r) for r in s.scalars(stmt)]

    def latest_run(self, **filters: Any) -> RunRecord | None:
        """The newest run matching :meth:`runs`' filters, or ``None``."""
        found = self.runs(**filters)
        return found[-1] if found else None

    def child_runs(self, run_id: int, kind: str | None = "eval") -> list[RunRecord]:
        """Runs whose parent is ``run_id`` (evaluations of a trained policy), oldest first."""
        stmt = select(RunRow).where(RunRow.parent_run_id == run_id).order_by(RunRow.id)
        if kind:
            stmt = stmt.where(RunRow.kind == kind)
        with self._read() as s:
            return [run_record(r) for r in s.scalars(stmt)]

    # ------------------------------------------------------------------ episodes
    def episodes(self, task_id: str | None = None, backend: str | None = None,
                 datapacks: Sequence[str] | str | None = None, objective: str | None = None,
                 kind: str | None = None, status: str | None = "completed",
                 run_ids: Iterable[int] | None = None) -> list[EpisodeRecord]:
        """Per-episode summaries of matching runs, ordered by run then episode index."""
        cols = (EpisodeRow.run_id, EpisodeRow.episode_index, EpisodeRow.termination_reason, EpisodeRow.summary)
        stmt = filter_runs(select(*cols).join(RunRow, EpisodeRow.run_id == RunRow.id),
                           task_id, backend, datapacks, objective, kind, status)
        run_stmt = filter_runs(select(RunRow), task_id, backend, datapacks, objective, kind, status)
        if run_ids is not None:
            stmt = stmt.where(RunRow.id.in_(list(run_ids)))
            run_stmt = run_stmt.where(RunRow.id.in_(list(run_ids)))
        stmt = stmt.order_by(EpisodeRow.run_id, EpisodeRow.episode_index)
        with self._read() as s:  # plain column rows: no ORM object per episode
            runs = {r.id: r for r in s.scalars(run_stmt)}
            return [episode_record(row, runs[row.run_id]) for row in s.execute(stmt)]

    def episode_arrays(self, keys: Sequence[str] = EPISODE_COLUMNS, **filters: Any) -> dict[str, np.ndarray]:
        """Column arrays (float64, NaN where missing) of :meth:`episodes`' rows plus ``run_id``.

        ``keys`` must be among ``EPISODE_COLUMNS``; filters as in :meth:`episodes`.
        """
        bad = [k for k in keys if k not in EPISODE_COLUMNS]
        if bad:
            raise UnknownNameError("episode column", bad[0], EPISODE_COLUMNS)
        cols = [EpisodeRow.run_id] + [getattr(EpisodeRow, k) for k in keys]
        run_ids = filters.pop("run_ids", None)
        stmt = filter_runs(select(*cols).join(RunRow, EpisodeRow.run_id == RunRow.id),
                       filters.pop("task_id", None), filters.pop("backend", None),
                       filters.pop("datapacks", None), filters.pop("objective", None),
                       filters.pop("kind", None), filters.pop("status", "completed"))
        if filters:
            raise TypeError(f"unknown filters: {sorted(filters)}")
        if run_ids is not None:
            stmt = stmt.where(RunRow.id.in_(list(run_ids)))
        with self._read() as s:
            rows = s.execute(stmt.order_by(EpisodeRow.run_id, EpisodeRow.episode_index)).all()
        data = np.array([[np.nan if v is None else v for v in row] for row in rows], dtype=np.float64)
        data = data.reshape(len(rows), len(cols))
        out = {"run_id": data[:, 0].astype(np.int64)}
        out.update({k: data[:, i + 1] for i, k in enumerate(keys)})
        return out

    # ------------------------------------------------------------------ reports
    def reports(self, task_id: str | None = None) -> list[ReportRecord]:
        stmt = select(ReportRow).order_by(ReportRow.id)
        if task_id:
            stmt = stmt.where(ReportRow.task_id == task_id)
        with self._read() as s:
            return [report_record(r) for r in s.scalars(stmt)]
