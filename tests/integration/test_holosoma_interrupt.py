"""A SIGTERM to a Holosoma ``report --policy`` while its sim-to-sim episodes run: the command stops by itself,
records the evaluation run as interrupted, leaves no worker behind and exits 143, as a shell reports SIGTERM
(it exited 130: Typer turned the KeyboardInterrupt into exit 130, whatever the signal)."""

from __future__ import annotations

import os
import sqlite3
import subprocess
import sys
import time
from pathlib import Path

import pytest

from .conftest import sigterm_when

pytestmark = [pytest.mark.holosoma]
ECONMOTOR = Path(sys.executable).with_name("econmotor")


def run_status(db: Path) -> str | None:
    """The status of the registry's only run, or None before it is recorded."""
    if not db.exists():
        return None
    with sqlite3.connect(db, timeout=30) as conn:
        try:
            row = conn.execute("SELECT status FROM runs").fetchone()
        except sqlite3.OperationalError:  # tables not created yet
            return None
    return row[0] if row else None


def test_sigterm_to_a_holosoma_report_exits_143_and_records_the_run_as_interrupted(tmp_path: Path) -> None:
    db = tmp_path / "registry.sqlite"
    args = ["report", "--task-id", "humanoid_locomotion_g1", "--motor-backend", "holosoma", "--policy",
            "holosoma:g1_29dof/ppo", "--eval-episodes", "40", "--db-url", f"sqlite:///{db}", "--output-dir",
            str(tmp_path / "out")]
    proc = subprocess.Popen([str(ECONMOTOR), *args], cwd=tmp_path, env={**os.environ, "OMP_NUM_THREADS": "1"},
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True)
    err = sigterm_when(proc, lambda: run_status(db) == "running", "the evaluation run's record",
                       settle_s=3)  # inside the episodes
    assert proc.returncode == 143, err[-2000:]  # 128 + SIGTERM
    assert "interrupted (signal SIGTERM)" in err and "still busy" not in err  # it stopped by itself
    assert run_status(db) == "interrupted"
    assert group_ends(proc.pid, within_s=10.0), left_in_group(proc.pid)  # no sim-to-sim worker outlives it


def group_ends(pgid: int, within_s: float) -> bool:
    """Whether process group ``pgid`` is gone within ``within_s`` seconds (its workers end as their pipes close)."""
    deadline = time.monotonic() + within_s
    while time.monotonic() < deadline:
        try:
            os.killpg(pgid, 0)
        except ProcessLookupError:
            return True
        time.sleep(0.1)
    return False


def left_in_group(pgid: int) -> str:
    """The processes still in group ``pgid``, one per line."""
    ps = subprocess.run(["ps", "-eo", "pid,pgid,stat,cmd"], capture_output=True, text=True).stdout
    return "\n".join(line for line in ps.splitlines()[1:] if line.split()[1] == str(pgid))
