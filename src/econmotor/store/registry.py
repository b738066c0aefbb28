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
kill -9, a power cut) as ``abandoned``, so no dead run stays ``running``.
Get-or-create of tasks, robots and datapacks is one ``INSERT ... ON CONFLICT`` statement
(SQLite and PostgreSQL), so concurrent first uses of a new task never fail on a unique key.
A report row is committed only after its files are written (:meth:`Registry.record_report`).
The schema is versioned (``econmotor_schema``); a database written by another schema
version is refused with a message saying what to do.
"""

from __future__ import annotations

import contextlib
import os
import socket
from collections.abc import Iterable, Iterator, Mapping, Sequence
from pathlib import Path
from typing import Any, Self

import numpy as np
from sqlalchemy import create_engine, func, inspect, select, text
from sqlalchemy.engine import Engine, make_url
from sqlalchemy.exc import SQLAlchemyError
from sqlalchemy.orm import Session

from econmotor.errors import ConfigError, RegistryError, UnknownNameError
from econmotor.motor_backend.datapacks import DatapackConfig, parse_datapack
from econmotor.motor_backend.results import PROVENANCE_KEY
from econmotor.store.engine import (
    DB_URL_ENV,
    check_db_url,
    default_db_url,
    make_sqlite_concurrent,
    registry_exists,
    sqlite_path,
)
from econmotor.store.models import (
    EPISODE_COLUMNS,
    RUN_KINDS,
    Base,
    DatapackRow,
    EpisodeRow,
    ReportRow,
    RobotRow,
    RunDatapackRow,
    RunRow,
    SchemaVersionRow,
    TaskRow,
    utc_now,
)
from econmotor.store.queries import check_status, episode_row, filter_runs
from econmotor.store.records import (
    EpisodeRecord,
    ReportRecord,
    RunRecord,
    episode_record,
    report_record,
    run_record,
)

__all__ = ["DB_URL_ENV", "Registry", "default_db_url", "registry_exists"]


class Registry:
    """Record and query runs (see the module docstring for usage).

    Args:
        url: SQLAlchemy URL; ``None`` means :func:`default_db_url` in the current directory.
        create: create the SQLite file and the tables when missing; with ``False`` a missing
            database is a :class:`RegistryError`.
        busy_timeout_s: how long a SQLite writer waits for another writer before failing.
    """

    def __init__(self, url: str | None = None, *, create: bool = True, busy_timeout_s: float = 120.0) -> None:
        self.url = url or default_db_url()
        try:
            check_db_url(self.url, "database URL")
        except ConfigError as exc:
            raise RegistryError(f"invalid database URL {self.url!r}: {exc.detail} "
                                f"(supported: {exc.allowed})") from None
        parsed = make_url(self.url)
        self.display_url = parsed.render_as_string(hide_password=True)
        path = sqlite_path(self.url)
        if path is not None:
            if not path.exists() and not create:
                raise RegistryError(f"no registry at {path}; run `econmotor report` first or pass --db-url")
            try:
                path.parent.mkdir(parents=True, exist_ok=True)
            except OSError as exc:
                raise RegistryError(f"cannot create the registry directory {path.parent}: {exc.strerror or exc}; "
                                    f"pass --db-url (or set {DB_URL_ENV}) to a writable location") from None
        self._sqlite = parsed.get_backend_name() == "sqlite"
        kwargs: dict[str, Any] = {}
        if self._sqlite:
            kwargs["connect_args"] = {"timeout": busy_timeout_s}
        try:
            self.engine: Engine = create_engine(self.url, **kwargs)
        except (SQLAlchemyError, ImportError) as exc:
            raise RegistryError(f"cannot use the database URL {self.display_url}: {exc}") from None
        if self._sqlite:
            make_sqlite_concurrent(self.engine, busy_timeout_s)
        self._ensure_schema(create)
        self.abandoned_run_ids = self._mark_abandoned_runs()

    # ------------------------------------------------------------------ schema
    def _ensure_schema(self, create: bool) -> None:
        from econmotor.store.models import SCHEMA_VERSION

        try:
            with self.engine.begin() as conn:
                if conn.dialect.name == "postgresql":  # serialise concurrent first use
                    conn.execute(text("SELECT pg_advisory_xact_lock(7270001)"))
                tables = set(inspect(conn).get_table_names())
                if SchemaVersionRow.__tablename__ not in tables:
                    if tables & set(Base.metadata.tables):
                        raise RegistryError(
                            f"{self.display_url} holds econmotor tables but no schema version; "
                            "it was not written by this econmotor: use a new database (--db-url)")
                    if not create:
                        raise RegistryError(f"{self.display_url} has no econmotor registry")
                    Base.metadata.create_all(conn)
                    conn.execute(SchemaVersionRow.__table__.insert().values(version=SCHEMA_VERSION,
                                                                            created_at=utc_now()))
                    return
                versions = [row[0] for row in conn.execute(select(SchemaVersionRow.version))]
        except SQLAlchemyError as exc:
            raise RegistryError(f"cannot open the registry at {self.display_url}: {exc}") from exc
        if versions != [SCHEMA_VERSION]:
            raise RegistryError(
                f"registry {self.display_url} has schema version {versions}, this econmotor uses "
                f"{SCHEMA_VERSION}; move the database aside (or pass --db-url to a new one) and "
                "re-run, or use the econmotor version that wrote it")

    @contextlib.contextmanager
    def _write(self) -> Iterator[Session]:
        """One transaction; database errors become RegistryError."""
        try:
            with Session(self.engine, expire_on_commit=False) as session, session.begin():
                yield session
        except SQLAlchemyError as exc:
            raise RegistryError(f"registry write failed ({self.display_url}): {exc}") from exc

    _read = _write

    def _upsert(self, session: Session, row_class: type, values: Mapping[str, Any], update: bool) -> None:
        """Get-or-create (``update=False``) or insert-or-update one row by primary key, race-free:
        one ``INSERT ... ON CONFLICT`` statement, so concurrent writers never hit a unique violation."""
        table = row_class.__table__
        if self._sqlite:
            from sqlalchemy.dialects.sqlite import insert
        else:
            from sqlalchemy.dialects.postgresql import insert
        stmt = insert(table).values(**values)
        keys = [c.name for c in table.primary_key]
        changed = {k: stmt.excluded[k] for k in values if k not in keys}
        stmt = stmt.on_conflict_do_update(index_elements=keys, set_=changed) if update and changed \
            else stmt.on_conflict_do_nothing(index_elements=keys)
        session.execute(stmt)

    # ------------------------------------------------------------------ run owners
    def _mark_abandoned_runs(self) -> list[int]:
        """Mark ``running`` runs whose owner process on this host is gone as ``abandoned``."""
        host = socket.gethostname()
        with self._read() as s:
            running = s.execute(select(RunRow.id, RunRow.config).where(RunRow.status == "running")).all()
        gone = [run_id for run_id, config in running
                if isinstance(owner := (config or {}).get("owner"), dict) and owner.get("host") == host
                and not _process_alive(owner.get("pid"), owner.get("start"))]
        if gone:
            with self._write() as s:
                for run_id in gone:
                    run = s.get(RunRow, run_id)
                    if run is not None and run.status == "running":
                        owner = run.config["owner"]
                        run.status, run.finished_at = "abandoned", utc_now()
                        run.error = (f"abandoned: its process {owner.get('pid')} on {host} ended without "
                                     "recording an outcome (killed?)")
        return gone

    def close(self) -> None:
        self.engine.dispose()

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

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
        _URLS_WITH_OWN_RUNS.add(self.url)
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

    @staticmethod
    def _get_run(session: Session, run_id: int) -> RunRow:
        run = session.get(RunRow, run_id)
        if run is None:
            raise RegistryError(f"no run with id {run_id} in the registry")
        return run

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

    def reports(self, task_id: str | None = None) -> list[ReportRecord]:
        stmt = select(ReportRow).order_by(ReportRow.id)
        if task_id:
            stmt = stmt.where(ReportRow.task_id == task_id)
        with self._read() as s:
            return [report_record(r) for r in s.scalars(stmt)]


#: registries this process has started runs in (for :func:`interrupt_own_runs`).
_URLS_WITH_OWN_RUNS: set[str] = set()


def interrupt_own_runs(reason: str, busy_timeout_s: float = 2.0) -> list[int]:
    """Mark this process's ``running`` runs ``interrupted`` (error ``reason``) in every registry it
    started runs in; returns their ids.

    The last word of a process that must end now (the CLI's interrupt deadline, when the main thread
    is stuck in a call that cannot be interrupted): a connection of its own with a short busy
    timeout, so a transaction left open by the main thread cannot hold it up.
    """
    me = run_owner()
    marked: list[int] = []
    for url in sorted(_URLS_WITH_OWN_RUNS):
        try:
            registry = Registry(url, create=False, busy_timeout_s=busy_timeout_s)
        except RegistryError:
            continue
        try:
            with registry._write() as s:
                for run in s.execute(select(RunRow).where(RunRow.status == "running")).scalars():
                    owner = (run.config or {}).get("owner") or {}
                    if owner.get("host") == me["host"] and owner.get("pid") == me["pid"]:
                        run.status, run.error, run.finished_at = "interrupted", reason, utc_now()
                        marked.append(run.id)
        except RegistryError:
            pass
        finally:
            registry.close()
    return marked


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


def _process_start(pid: int) -> str | None:
    """The start time of process ``pid`` (clock ticks since boot, from /proc), or None where unknown."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return None
    return stat.rsplit(")", 1)[-1].split()[19]


def run_owner() -> dict[str, Any]:
    """Who runs this process: host, pid and the process start time (tells a reused pid apart)."""
    pid = os.getpid()
    return {"host": socket.gethostname(), "pid": pid, "start": _process_start(pid)}


def _process_alive(pid: Any, start: Any) -> bool:
    """Whether process ``pid`` (started at ``start``, when recorded) still runs on this host."""
    if not isinstance(pid, int) or pid <= 0:
        return True  # unknown owner: never guess it dead
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        pass  # exists, another user's
    try:
        if Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[-1].split()[0] in ("Z", "X"):
            return False  # killed, not yet reaped
    except (OSError, IndexError):
        pass
    now = _process_start(pid)
    return start is None or now is None or now == start
