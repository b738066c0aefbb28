"""The run registry: tasks, robots, datapacks, runs, episodes and reports in one database.

SQLite file by default (``./.econmotor/registry.sqlite``, created on first use),
PostgreSQL (or any SQLAlchemy URL) by ``Registry(url)``. The CLI reads the URL from
``--db-url`` or the ``ECONMOTOR_DB_URL`` environment variable; library code takes it
as an argument. Usage from library code::

    from econmotor.store import Registry

    reg = Registry()                                   # or Registry("postgresql+psycopg://...")
    reg.record_task(spec)                              # a TaskSpec from econmotor.tasks
    reg.record_datapacks(configs)                      # DatapackConfig list; ids become reusable
    with reg.track_run("train", spec.task_id, "dishwashing", objective=obj,
                       datapack_ids=["dr_v1"], seed=0, num_envs=1, max_steps=2000) as run_id:
        result = backend.train_policy(...)             # failure -> status failed / interrupted
        reg.finish_run(run_id, result)                 # metrics + episodes, one transaction
    # or, for a result already in hand (one transaction):
    run_id = reg.record_run("eval", result, objective=obj, datapack_ids=["dr_v1"], seed=1)

    reg.runs(task_id="dishwashing", status="completed")            # -> [RunRecord]
    reg.episodes(task_id="dishwashing", backend="dishwashing",
                 datapacks=["dr_v1"], objective="throughput")      # -> [EpisodeRecord]
    reg.episode_arrays(["mpl_units_per_hour", "error_rate"], task_id="dishwashing")  # numpy

Filters: ``datapacks`` keeps runs that used every listed id (``[]`` keeps runs that used
none); ``objective`` matches the objective name. ``episodes`` reads completed runs by
default. Every write is one transaction. On SQLite the database runs in WAL mode with a
busy timeout and every transaction begins ``IMMEDIATE``, so several processes can write
one file at once: writers queue instead of failing or corrupting. A run is recorded as
``running`` before work starts, so a crash or Ctrl-C leaves it ``failed`` /
``interrupted`` (via :meth:`track_run`) and never loses what was already committed.
A run records its owner (host, pid and the process's start time, in ``config["owner"]``);
opening a registry marks ``running`` runs whose owner process on this host is gone (a
kill -9, a power cut) as ``abandoned``, so no dead run stays ``running``
(:mod:`econmotor.store.owners`).
Get-or-create of tasks, robots and datapacks is one ``INSERT ... ON CONFLICT`` statement
(SQLite and PostgreSQL), so concurrent first uses of a new task never fail on a unique key.
A report row is committed only after its files are written (:meth:`Registry.record_report`).
The schema is versioned (``econmotor_schema``); a database written by another schema
version is refused with a message saying what to do.

This module holds :class:`Registry` and its writes; opening the database, transactions and the
schema check are :mod:`econmotor.store.database`, the queries :mod:`econmotor.store.reads`.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterable, Iterator, Mapping, Sequence
from pathlib import Path
from typing import Any

from sqlalchemy import func, select

from econmotor.config.datapacks import DatapackConfig
from econmotor.errors import RegistryError
from econmotor.motor_backend.results import PROVENANCE_KEY
from econmotor.store.models import (
    RUN_KINDS,
    DatapackRow,
    EpisodeRow,
    ReportRow,
    RobotRow,
    RunDatapackRow,
    RunRow,
    TaskRow,
    utc_now,
)
from econmotor.store.owners import mark_abandoned_runs, remember_own_runs, run_owner
from econmotor.store.queries import check_status, episode_row
from econmotor.store.reads import RegistryReads

__all__ = ["Registry", "result_config"]


class Registry(RegistryReads):
    """Record and query runs (see the module docstring for usage).

    Args:
        url: SQLAlchemy URL; ``None`` means :func:`default_db_url` in the current directory.
        create: create the SQLite file and the tables when missing; with ``False`` a missing
            database is a :class:`RegistryError`.
        busy_timeout_s: how long a SQLite writer waits for another writer before failing.

    Opening it marks abandoned runs (:func:`econmotor.store.owners.mark_abandoned_runs`); their ids
    are ``abandoned_run_ids``.
    """

    def __init__(self, url: str | None = None, *, create: bool = True, busy_timeout_s: float = 120.0) -> None:
        super().__init__(url, create=create, busy_timeout_s=busy_timeout_s)
        self.abandoned_run_ids = mark_abandoned_runs(self)

    # ------------------------------------------------------------------ catalog rows
    def record_task(self, spec: Any) -> None:
        """Insert or update a task (a ``econmotor.tasks.TaskSpec``) with its economics."""
        with self._write() as s:
            self._upsert(s, TaskRow, {
                "task_id": spec.task_id, "description": spec.description, "unit": spec.unit,
                "error_definition": spec.error_definition,
                "economics": {"values": spec.economics.to_dict(), "parameters": spec.economics.parameters()},
                "source": spec.source, "updated_at": utc_now()}, update=True)

    def record_robot(self, robot_id: str, backend: str, description: str = "",
                     details: Mapping[str, Any] | None = None) -> None:
        """Insert or update a robot: ``robot_id`` names it apart from any backend (``"hopper"``, ``"g1_29dof"``:
        ``MotorBackendBase.robot_id``; registries written before name it ``"<backend>:<env or robot>"``),
        ``backend`` the backend that recorded it last."""
        with self._write() as s:
            self._upsert(s, RobotRow, {"robot_id": robot_id, "backend": backend, "description": description,
                                       "details": dict(details or {})}, update=True)

    def record_datapacks(self, configs: Iterable[DatapackConfig]) -> list[str]:
        """Insert or update datapacks so later runs can name them by id; returns the ids."""
        configs = list(configs)
        with self._write() as s:  # in id order: concurrent writers lock rows in the same order
            for config in sorted(configs, key=lambda c: c.id):
                self._upsert(s, DatapackRow, {"datapack_id": config.id, "description": config.description,
                                              "config": config.to_dict(), "source": config.source,
                                              "registered_at": utc_now()}, update=True)
        return [c.id for c in configs]

    # ------------------------------------------------------------------ runs
    def start_run(
        self,
        kind: str,
        task_id: str,
        backend: str,
        *,
        objective: Any = None,
        datapack_ids: Sequence[str] = (),
        config: Mapping[str, Any] | None = None,
        seed: int | None = None,
        num_envs: int | None = None,
        max_steps: int | None = None,
        notes: str = "",
        parent_run_id: int | None = None,
        robot_id: str | None = None,
        policy_path: str | None = None,
    ) -> int:
        """Record a run as ``running`` (committed at once) and return its id.

        ``objective`` is an ``EconomicObjectiveSpec`` (or its ``to_dict()``); the task row is
        created with empty economics if it was not recorded before.
        """
        if kind not in RUN_KINDS:
            raise RegistryError(f"run kind must be one of {RUN_KINDS}, got {kind!r}")
        obj = objective.to_dict() if hasattr(objective, "to_dict") else dict(objective or {})
        ids = list(dict.fromkeys(datapack_ids))
        with self._write() as s:
            self._upsert(s, TaskRow, _new_task_values(task_id), update=False)
            if robot_id is not None:
                self._upsert(s, RobotRow, {"robot_id": robot_id, "backend": backend, "description": "",
                                           "details": {}}, update=False)
            run = RunRow(kind=kind, parent_run_id=parent_run_id, task_id=task_id, backend=backend,
                         robot_id=robot_id, objective_name=str(obj.get("name", "objective")),
                         objective=obj, datapack_ids=ids, config={**dict(config or {}), "owner": run_owner()},
                         seed=seed,
                         num_envs=num_envs, max_steps=max_steps, notes=notes, status="running",
                         policy_path=policy_path, created_at=utc_now())
            s.add(run)
            s.flush()
            s.add_all(RunDatapackRow(run_id=run.id, datapack_id=d, position=i) for i, d in enumerate(ids))
        remember_own_runs(self.url)
        return run.id

    def finish_run(self, run_id: int, result: Any = None, *, status: str = "completed",
                   episodes: Sequence[Mapping[str, Any]] | None = None, **fields: Any) -> None:
        """Store a run's outcome and its episodes in one transaction.

        Args:
            run_id: from :meth:`start_run`.
            result: a ``MotorTrainingResult`` / ``MotorEvalResult`` (policy path, metrics,
                episodes, training curve, config, artifacts are taken from it; the run's config
                records the result's under ``backend_config`` and an evaluation's provenance under
                ``provenance``: :func:`result_config`), or ``None``.
            status: the final status.
            episodes: per-episode summaries (default: ``result.episodes``).
            **fields: run columns to set directly (``raw_metrics``, ``error``, ...).
        """
        check_status(status)
        values: dict[str, Any] = {}
        if result is not None:
            values = {"policy_path": result.policy_id, "raw_metrics": dict(result.raw_metrics),
                      "econ_metrics": dict(result.econ_metrics),
                      "training_curve": list(getattr(result, "training_curve", []) or []),
                      "artifacts": dict(getattr(result, "artifacts", {}) or {})}
            episodes = result.episodes if episodes is None else episodes
        values.update(fields)
        with self._write() as s:
            run = self._get_run(s, run_id)
            if result is not None:
                run.config = {**run.config, **result_config(result)}
            for key, value in values.items():
                setattr(run, key, value)
            run.status, run.finished_at = status, utc_now()
            if episodes:
                s.add_all(episode_row(run_id, ep, i) for i, ep in enumerate(episodes))

    def mark_run(self, run_id: int, status: str, error: str | None = None) -> None:
        """Set a run's status (e.g. ``failed`` with the error text); keeps everything else."""
        check_status(status)
        with self._write() as s:
            run = self._get_run(s, run_id)
            run.status, run.error, run.finished_at = status, error, utc_now()

    @contextlib.contextmanager
    def track_run(self, kind: str, task_id: str, backend: str, **kwargs: Any) -> Iterator[int]:
        """``start_run`` now; if the body raises, mark the run failed (or interrupted on
        Ctrl-C / SystemExit) with the error text and re-raise. The body calls :meth:`finish_run`."""
        run_id = self.start_run(kind, task_id, backend, **kwargs)
        try:
            yield run_id
        except (KeyboardInterrupt, SystemExit) as exc:
            self._mark_if_running(run_id, "interrupted", f"{type(exc).__name__}: {exc}")
            raise
        except BaseException as exc:
            self._mark_if_running(run_id, "failed", f"{type(exc).__name__}: {exc}")
            raise

    def _mark_if_running(self, run_id: int, status: str, error: str) -> None:
        if self.run(run_id).status == "running":
            self.mark_run(run_id, status, error)

    def record_run(self, kind: str, result: Any, *, objective: Any = None, datapack_ids: Sequence[str] = (),
                   status: str = "completed", **kwargs: Any) -> int:
        """Record a finished run from a backend result (with its episodes); returns its id.

        ``kwargs`` go to :meth:`start_run` (``seed``, ``num_envs``, ``max_steps``, ``notes``,
        ``config``, ``parent_run_id``, ``robot_id``).
        """
        run_id = self.start_run(kind, result.task_id, result.backend, objective=objective,
                                datapack_ids=datapack_ids, **kwargs)
        self.finish_run(run_id, result, status=status)
        return run_id

    def record_episodes(self, run_id: int, episodes: Sequence[Mapping[str, Any]]) -> int:
        """Append per-episode summaries to a run (indices continue); returns how many."""
        with self._write() as s:
            self._get_run(s, run_id)
            start = s.scalar(select(func.count()).select_from(EpisodeRow).where(EpisodeRow.run_id == run_id))
            s.add_all(episode_row(run_id, ep, start + i) for i, ep in enumerate(episodes))
        return len(episodes)

    # ------------------------------------------------------------------ reports
    def record_report(self, task_id: str, document: Mapping[str, Any], files: Mapping[str, str],
                      train_run_id: int | None = None, eval_run_id: int | None = None,
                      write_files: Any = None) -> int:
        """Record a report; returns its id.

        With ``write_files(report_id) -> {kind: path}`` the files are written inside the
        transaction and the row commits only if they all exist afterwards: a failed (or
        killed) write leaves no row naming missing files.
        """
        with self._write() as s:
            self._upsert(s, TaskRow, _new_task_values(task_id), update=False)
            row = ReportRow(task_id=task_id, document=dict(document), files=dict(files),
                            train_run_id=train_run_id, eval_run_id=eval_run_id, created_at=utc_now())
            s.add(row)
            s.flush()
            if write_files is not None:
                written = {k: str(v) for k, v in write_files(row.id).items()}
                missing = [p for p in written.values() if not Path(p).is_file()]
                if missing:
                    raise RegistryError(f"report files missing after writing: {', '.join(missing)}")
                row.files = written
            return row.id


def result_config(result: Any) -> dict[str, Any]:
    """What a run's config records of a backend result: its ``config`` as ``backend_config`` (the backend's
    own keys) and, for an evaluation, its provenance under ``PROVENANCE_KEY`` (``MotorEvalResult.provenance``,
    the contract's declared fields: evaluator, where the figures come from, speeds, power), where report and
    compare read it."""
    provenance = getattr(result, "provenance", None)
    own = {k: v for k, v in (result.config or {}).items() if provenance is None or k != PROVENANCE_KEY}
    return {**({"backend_config": own} if own else {}),
            **({PROVENANCE_KEY: provenance.to_dict()} if provenance is not None else {})}


def _new_task_values(task_id: str) -> dict[str, Any]:
    """Column values of a task row created on first use (economics recorded later by record_task)."""
    return {"task_id": task_id, "description": "", "unit": "", "error_definition": "", "economics": {},
            "source": "", "updated_at": utc_now()}
