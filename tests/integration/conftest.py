"""Fixtures of the end-to-end tests: ``workdir``, and a throwaway PostgreSQL server (``pg_server``, ``pg_url``);
:func:`sigterm_when`, a command line stopped the way a shell's ``kill`` stops it.

Started on loopback once per session: initdb into a temporary directory, pg_ctl on a free
port (as the ``postgres`` user when running as root, since PostgreSQL refuses root).
``.ci/run`` installs Debian's postgresql first. Where the server cannot be started the
tests are skipped with the reason printed, except in CI (the ``CI`` environment variable
is set): there they FAIL, so a broken PostgreSQL setup is never a silent pass.
"""

from __future__ import annotations

import glob
import os
import pwd
import shutil
import signal
import socket
import subprocess
import tempfile
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest


def in_ci() -> bool:
    return os.environ.get("CI", "").strip().lower() not in ("", "0", "false", "no")


def unavailable(reason: str) -> None:
    """Fail in CI, skip elsewhere (with the reason printed either way)."""
    print(f"PostgreSQL unavailable: {reason}")
    if in_ci():
        pytest.fail(f"CI is set and a PostgreSQL test cannot run: {reason}", pytrace=False)
    pytest.skip(reason)


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


@pytest.fixture(scope="session")
def pg_server() -> Iterator[tuple[str, int]]:
    bin_dir = _pg_bin_dir()
    if bin_dir is None:
        unavailable("PostgreSQL binaries (initdb, pg_ctl) not found; install Debian's postgresql to run these")
    try:
        import psycopg  # noqa: F401
    except ImportError:
        unavailable("psycopg is not installed (pip install 'psycopg[binary]')")
    root = Path(tempfile.mkdtemp(prefix="econmotor-pg-"))
    data, port = root / "data", _free_port()
    prefix: list[str] = []
    if os.geteuid() == 0:  # PostgreSQL refuses to run as root
        try:
            user = pwd.getpwnam("postgres")
        except KeyError:
            unavailable("running as root and no 'postgres' user exists to own the server")
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
REPO = Path(__file__).resolve().parents[2]


@pytest.fixture
def workdir(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """An empty working directory with the repository's configs/ reachable as ./configs."""
    (tmp_path / "configs").symlink_to(REPO / "configs")
    monkeypatch.chdir(tmp_path)
    monkeypatch.delenv("ECONMOTOR_DB_URL", raising=False)
    return tmp_path


def sigterm_when(proc: subprocess.Popen, ready: Callable[[], bool], waiting_for: str, settle_s: float = 0.0,
                 hang_s: float = 180.0) -> str:
    """SIGTERM ``proc`` (started with ``start_new_session``, stderr piped as text) ``settle_s`` seconds after
    ``ready()``; its stderr. Fails if it ends first or ``waiting_for`` does not come within ``hang_s``; its
    process group is killed whatever happens, so nothing outlives the test."""
    try:
        deadline = time.monotonic() + hang_s
        while not ready():
            assert proc.poll() is None, proc.communicate()[1][-2000:]
            assert time.monotonic() < deadline, f"{waiting_for} did not come within {hang_s:g} s"
            time.sleep(0.1)
        time.sleep(settle_s)
        proc.send_signal(signal.SIGTERM)
        return proc.communicate(timeout=60)[1]
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.communicate(timeout=30)
