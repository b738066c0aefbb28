"""Connecting to the registry database: URLs, the default SQLite file, SQLite concurrency settings."""

from __future__ import annotations

import sqlite3
import time
from pathlib import Path
from typing import Any

from sqlalchemy import event
from sqlalchemy.engine import Engine, make_url
from sqlalchemy.exc import SQLAlchemyError

from econmotor.errors import ConfigError

#: Environment variable the CLI reads for the database URL.
DB_URL_ENV = "ECONMOTOR_DB_URL"
_SQLITE_FILE = Path(".econmotor") / "registry.sqlite"


def default_db_url(base_dir: str | Path | None = None) -> str:
    """``sqlite:///<base_dir or cwd>/.econmotor/registry.sqlite`` (absolute path)."""
    return f"sqlite:///{(Path(base_dir or Path.cwd()) / _SQLITE_FILE).resolve()}"


#: Registry URL schemes econmotor supports (SQLAlchemy dialect+driver).
SUPPORTED_DB_SCHEMES = ("sqlite:///PATH", "postgresql://...", "postgresql+psycopg://...")
_SUPPORTED_BACKENDS = ("sqlite", "postgresql")


def check_db_url(url: str, source: str = "--db-url") -> str:
    """A ConfigError (naming ``source``) unless ``url`` parses, is SQLite or PostgreSQL and its
    driver is installed; returns ``url``."""
    allowed = ", ".join(SUPPORTED_DB_SCHEMES)
    try:
        parsed = make_url(url)
    except (SQLAlchemyError, ValueError, TypeError) as exc:
        raise ConfigError(source, None, f"not a database URL ({' '.join(str(exc).split())})", allowed) from None
    if parsed.get_backend_name() not in _SUPPORTED_BACKENDS:
        raise ConfigError(source, None, f"unsupported database scheme '{parsed.drivername}'", allowed)
    try:
        parsed.get_dialect()
    except (SQLAlchemyError, ImportError) as exc:
        raise ConfigError(source, None, f"cannot use '{parsed.drivername}': {' '.join(str(exc).split())}; "
                          "for PostgreSQL install psycopg (pip install 'psycopg[binary]')", allowed) from None
    return url


def sqlite_path(url: str) -> Path | None:
    """The database file of a SQLite URL, ``None`` for other databases or in-memory SQLite."""
    parsed = make_url(url)
    if parsed.get_backend_name() != "sqlite" or parsed.database in (None, "", ":memory:"):
        return None
    return Path(parsed.database)


def registry_exists(url: str) -> bool:
    """False only for a SQLite file that does not exist yet (other URLs: assumed to exist)."""
    path = sqlite_path(url)
    return path is None or path.exists()


def make_sqlite_concurrent(engine: Engine, busy_timeout_s: float) -> None:
    """WAL + busy timeout + BEGIN IMMEDIATE: concurrent writers wait for each other.

    Deferred transactions that read then write can fail at once with SQLITE_BUSY
    (the busy handler is not used when upgrading a read lock); IMMEDIATE avoids that.
    """

    @event.listens_for(engine, "connect")
    def _on_connect(dbapi_conn: Any, _record: Any) -> None:
        dbapi_conn.isolation_level = None  # SQLAlchemy's "begin" event below emits BEGIN
        cursor = dbapi_conn.cursor()
        cursor.execute(f"PRAGMA busy_timeout = {int(busy_timeout_s * 1000)}")
        # switching a new file to WAL takes an exclusive lock and SQLite answers SQLITE_BUSY at
        # once, without the busy handler, while another process opens the same new file: retry
        deadline = time.monotonic() + busy_timeout_s
        while True:
            try:
                cursor.execute("PRAGMA journal_mode = WAL")
                break
            except sqlite3.OperationalError as exc:
                if "locked" not in str(exc) or time.monotonic() > deadline:
                    raise
                time.sleep(0.01)
        cursor.execute("PRAGMA synchronous = NORMAL")
        cursor.execute("PRAGMA foreign_keys = ON")
        cursor.close()

    @event.listens_for(engine, "begin")
    def _on_begin(conn: Any) -> None:
        conn.exec_driver_sql("BEGIN IMMEDIATE")
