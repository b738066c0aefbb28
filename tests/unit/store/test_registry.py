"""Registry behaviour on SQLite (the same checks run on PostgreSQL in tests/integration)."""

from __future__ import annotations

import importlib.util
import multiprocessing
import sqlite3
from pathlib import Path

import pytest

from econmotor.errors import RegistryError
from econmotor.store import Registry, default_db_url

_spec = importlib.util.spec_from_file_location("registry_contract", Path(__file__).with_name("registry_contract.py"))
contract = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(contract)


@pytest.mark.parametrize("check", contract.CHECKS, ids=lambda c: c.__name__.removeprefix("check_"))
def test_registry_contract_on_sqlite(check, tmp_path: Path) -> None:
    check(f"sqlite:///{tmp_path / 'registry.sqlite'}")


def test_default_registry_is_created_on_first_use_in_dot_econmotor(tmp_path: Path, monkeypatch) -> None:
    monkeypatch.chdir(tmp_path)
    assert default_db_url() == f"sqlite:///{tmp_path.resolve() / '.econmotor' / 'registry.sqlite'}"
    with pytest.raises(RegistryError, match="no registry at"):
        Registry(create=False)
    assert not (tmp_path / ".econmotor").exists()
    Registry().close()
    db = tmp_path / ".econmotor" / "registry.sqlite"
    assert db.is_file()
    with sqlite3.connect(db) as conn:
        assert conn.execute("PRAGMA journal_mode").fetchone()[0] == "wal"
        tables = {r[0] for r in conn.execute("SELECT name FROM sqlite_master WHERE type='table'")}
    assert {"econmotor_schema", "tasks", "robots", "datapacks", "runs", "episodes", "reports"} <= tables


def test_foreign_tables_without_a_version_are_refused(tmp_path: Path) -> None:
    db = tmp_path / "other.sqlite"
    with sqlite3.connect(db) as conn:
        conn.execute("CREATE TABLE runs (id INTEGER PRIMARY KEY)")
    with pytest.raises(RegistryError, match="no schema version"):
        Registry(f"sqlite:///{db}")


def test_invalid_url_is_a_registry_error() -> None:
    with pytest.raises(RegistryError, match="invalid database URL"):
        Registry("not a url")


def _writer(url: str, worker: int, runs: int) -> None:
    reg = Registry(url)
    for i in range(runs):
        run_id = reg.start_run("eval", "dishwashing", "dishwashing", seed=worker * 1000 + i)
        reg.finish_run(run_id, episodes=[{"mpl_units_per_hour": float(i), "episode_index": j} for j in range(3)])
    reg.close()


def test_processes_writing_one_sqlite_file_at_once_lose_nothing(tmp_path: Path) -> None:
    url = f"sqlite:///{tmp_path / 'registry.sqlite'}"
    ctx = multiprocessing.get_context("spawn")
    procs = [ctx.Process(target=_writer, args=(url, w, 40)) for w in range(3)]
    for p in procs:
        p.start()
    for p in procs:
        p.join(120)
    assert [p.exitcode for p in procs] == [0, 0, 0]
    reg = Registry(url)
    runs = reg.runs()
    assert len(runs) == 120 and {r.status for r in runs} == {"completed"}
    assert sorted(r.seed for r in runs) == sorted(w * 1000 + i for w in range(3) for i in range(40))
    assert len(reg.episodes()) == 360
