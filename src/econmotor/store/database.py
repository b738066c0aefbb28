"""Opening the registry database: the URL, the schema version, transactions and race-free upserts.

:class:`RegistryDatabase` is what every registry operation stands on: it checks the URL, creates
the SQLite file's directory (``create=True``) or refuses a missing database, opens the engine
(on SQLite in WAL mode with a busy timeout, every transaction ``IMMEDIATE``:
:func:`econmotor.store.engine.make_sqlite_concurrent`), and creates or checks the versioned schema
(``econmotor_schema``; a database written by another schema version is refused with a message
saying what to do). Every read and write is one transaction (:meth:`RegistryDatabase._write`), and
get-or-create is one ``INSERT ... ON CONFLICT`` statement (:meth:`RegistryDatabase._upsert`).
The registry's queries (:mod:`econmotor.store.reads`) and writes (:mod:`econmotor.store.registry`)
build on it.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator, Mapping
from typing import Any, Self

from sqlalchemy import create_engine, inspect, select, text
from sqlalchemy.engine import Engine, make_url
from sqlalchemy.exc import SQLAlchemyError
from sqlalchemy.orm import Session

from econmotor.errors import ConfigError, RegistryError
from econmotor.store.engine import DB_URL_ENV, check_db_url, default_db_url, make_sqlite_concurrent, sqlite_path
from econmotor.store.models import Base, RunRow, SchemaVersionRow, utc_now


class RegistryDatabase:
    """An open registry database (see the module docstring).

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

    # ------------------------------------------------------------------ transactions
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

    @staticmethod
    def _get_run(session: Session, run_id: int) -> RunRow:
        run = session.get(RunRow, run_id)
        if run is None:
            raise RegistryError(f"no run with id {run_id} in the registry")
        return run

    def close(self) -> None:
        self.engine.dispose()

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
