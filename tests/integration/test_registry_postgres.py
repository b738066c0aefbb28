"""The registry checks of tests/unit/store/registry_contract.py against a real PostgreSQL server.

A throwaway server is started on loopback (initdb into a temporary directory, pg_ctl on a
free port; as the ``postgres`` user when running as root, since PostgreSQL refuses root).
Where no PostgreSQL binaries exist the tests are skipped with the reason printed.
"""

from __future__ import annotations

import glob
import importlib.util
import os
import pwd
import shutil
import socket
import subprocess
import tempfile
from collections.abc import Iterator
from pathlib import Path

import pytest

pytestmark = pytest.mark.postgres

_spec = importlib.util.spec_from_file_location(
    "registry_contract", Path(__file__).parents[1] / "unit" / "store" / "registry_contract.py")
contract = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(contract)


def _pg_bin_dir() -> Path | None:
    found = shutil.which("initdb")
    if found:
        return Path(found).parent
    candidates = sorted(glob.glob("/usr/lib/postgresql/*/bin/initdb"), reverse=True)
    return Path(candidates[0]).parent if candidates else None


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture(scope="module")
def pg_server() -> Iterator[tuple[str, int]]:
    bin_dir = _pg_bin_dir()
    if bin_dir is None:
        reason = "PostgreSQL binaries (initdb, pg_ctl) not found; install Debian's postgresql to run these"
        print(f"SKIPPED: {reason}")
        pytest.skip(reason)
    pytest.importorskip("psycopg", reason="psycopg is not installed (pip install 'psycopg[binary]')")
    root = Path(tempfile.mkdtemp(prefix="econmotor-pg-"))
    data, port = root / "data", _free_port()
    prefix: list[str] = []
    if os.geteuid() == 0:  # PostgreSQL refuses to run as root
        try:
            user = pwd.getpwnam("postgres")
        except KeyError:
            pytest.skip("running as root and no 'postgres' user exists to own the server")
        os.chown(root, user.pw_uid, user.pw_gid)
        prefix = ["runuser", "-u", "postgres", "--"]
    run = lambda *cmd: subprocess.run([*prefix, *cmd], check=True, capture_output=True, text=True)
    try:
        run(str(bin_dir / "initdb"), "-D", str(data), "-A", "trust", "-U", "econ", "--no-sync")
        run(str(bin_dir / "pg_ctl"), "-D", str(data), "-l", str(root / "log"), "-w", "-t", "60", "-o",
            f"-p {port} -k {root} -c listen_addresses=127.0.0.1 -c fsync=off", "start")
    except subprocess.CalledProcessError as exc:
        shutil.rmtree(root, ignore_errors=True)
        pytest.fail(f"could not start PostgreSQL: {exc.stderr or exc.stdout}")
    try:
        yield "127.0.0.1", port
    finally:
        subprocess.run([*prefix, str(bin_dir / "pg_ctl"), "-D", str(data), "-m", "immediate", "stop"],
                       check=False, capture_output=True)
        shutil.rmtree(root, ignore_errors=True)


@pytest.fixture
def pg_url(pg_server: tuple[str, int], request: pytest.FixtureRequest) -> str:
    import psycopg

    host, port = pg_server
    name = "t_" + "".join(c if c.isalnum() else "_" for c in request.node.name.lower())[:50]
    with psycopg.connect(host=host, port=port, user="econ", dbname="postgres", autocommit=True) as conn:
        conn.execute(f'DROP DATABASE IF EXISTS "{name}"')
        conn.execute(f'CREATE DATABASE "{name}"')
    return f"postgresql+psycopg://econ@{host}:{port}/{name}"


@pytest.mark.parametrize("check", contract.CHECKS, ids=lambda c: c.__name__.removeprefix("check_"))
def test_registry_contract_on_postgresql(check, pg_url: str) -> None:
    check(pg_url)


def test_two_registries_creating_the_schema_at_once_on_postgresql(pg_url: str) -> None:
    from concurrent.futures import ThreadPoolExecutor

    from econmotor.store import Registry

    with ThreadPoolExecutor(2) as pool:
        regs = list(pool.map(lambda _: Registry(pg_url), range(2)))
    ids = [reg.start_run("train", "dishwashing", "dishwashing") for reg in regs]
    assert len(set(ids)) == 2 and len(regs[0].runs()) == 2
    for reg in regs:
        reg.close()


def test_report_from_a_postgresql_registry(pg_url: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    import json

    from econmotor.cli import main
    from econmotor.motor_backend.base import MotorEvalResult, summarize_episodes
    from econmotor.store import Registry
    from econmotor.tasks import get_task

    monkeypatch.chdir(tmp_path)
    task = get_task("dishwashing")
    raw, econ, eps = summarize_episodes([{"units_completed": 50, "errors": 0, "episode_length_s": 3600,
                                          "energy_wh": 100}], task.economics)
    with Registry(pg_url) as reg:
        run_id = reg.record_run("eval", MotorEvalResult("p", "dishwashing", "dishwashing", raw, econ, eps))
    monkeypatch.setenv("ECONMOTOR_DB_URL", pg_url)  # read at the CLI edge
    assert main(["report", "--motor-backend", "none", "--task-id", "dishwashing", "--output-dir", "out"]) == 0
    doc = json.loads((tmp_path / "out" / f"dishwashing_run{run_id}.json").read_text())
    # 50 dishes/h, 0.1 kWh/h: unit cost (1.75 + 0.9 + 2.0 + 0.012)/50 = 0.09324
    assert doc["pricing"]["aggregate"]["robot_unit_cost_usd"] == pytest.approx(0.09324)
    assert doc["registry"]["db_url"].startswith("postgresql+psycopg://econ@127.0.0.1")
    assert not (tmp_path / ".econmotor").exists()
    with Registry(pg_url) as reg:
        assert [r.id for r in reg.reports("dishwashing")] == [doc["registry"]["report_id"]]
