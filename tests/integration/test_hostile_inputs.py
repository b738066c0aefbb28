"""Hostile input through the real command line (``.venv/bin/econmotor`` in a child process).

An alias bomb ("billion laughs": 2 KB on disk, 9^9 strings once its aliases are written out)
as a datapack, a task file, an objective or a constraint set: every command that reads that
kind of YAML exits 2 with one line naming the file, in under 5 s (CPU time of the child: start-up
included; refusing the file itself takes milliseconds). And SIGTERM during a long
sweep (in this process, and on Ray) ends it within 10 s, the cell in flight recorded as
``interrupted``. Every child runs in its own process group, killed and reaped in ``finally``.
"""

from __future__ import annotations

import os
import resource
import signal
import sqlite3
import subprocess
import sys
import time
from pathlib import Path

import pytest

ECONMOTOR = Path(sys.executable).with_name("econmotor")
CHILD_ENV = {**os.environ, "OMP_NUM_THREADS": "1", "RAY_USAGE_STATS_ENABLED": "0", "RAY_DEDUP_LOGS": "0",
             "RAY_enable_metrics_collection": "0", "COLUMNS": "200"}


def bomb(indent: int) -> str:
    """Nine anchors, each a list of nine aliases of the one before, as mapping entries at ``indent``."""
    pad = " " * indent
    lines = [f"{pad}l0: &l0 [{', '.join(['lol'] * 9)}]"]
    lines += [f"{pad}l{i}: &l{i} [{', '.join([f'*l{i - 1}'] * 9)}]" for i in range(1, 9)]
    return "\n".join(lines) + "\n"


BOMBS = {
    "datapack": "id: bomb\ndomain_randomization:\n" + bomb(2),
    "tasks": ("tasks:\n  bomb:\n    unit: dish\n    economics:\n"
              "      wage_human_usd_per_hour: {value: 18.0, source: x}\n"
              "    backends:\n      dishwashing:\n        econ_overrides:\n" + bomb(10)),
    "objective": "name: bomb\nobjective_preset: throughput\nextra_weights:\n" + bomb(2),
    "constraints": "constraint_sets:\n  bomb:\n" + bomb(4),
}

#: (kind of YAML, command line with {file} and {tmp}): every command that reads that kind of file
COMMANDS = [
    ("datapack", "datapacks validate {file}"),
    ("datapack", "sweep --task-id dishwashing --datapacks {file} --output-dir {tmp}/sweep"),
    ("datapack", "train --task-id dishwashing --motor-backend dishwashing --datapacks {file} --output-dir {tmp}/run"),
    ("datapack", "evaluate --policy {tmp}/none --task-id dishwashing --motor-backend dishwashing --datapacks {file}"),
    ("datapack", "report --task-id dishwashing --motor-backend dishwashing --datapacks {file} --output-dir {tmp}/r"),
    ("tasks", "tasks --tasks-file {file}"),
    ("tasks", "report --task-id dishwashing --motor-backend dishwashing --tasks-file {file} --output-dir {tmp}/r"),
    ("objective", "train --task-id dishwashing --motor-backend dishwashing --objective-config {file} "
                  "--output-dir {tmp}/run"),
    ("objective", "evaluate --policy {tmp}/none --task-id dishwashing --motor-backend dishwashing "
                  "--objective-config {file}"),
    ("objective", "report --task-id dishwashing --motor-backend dishwashing --objective-config {file} "
                  "--output-dir {tmp}/r"),
    ("constraints", "solve --task-id dishwashing --constraints {file} --output-dir {tmp}/surface"),
    ("constraints", "shadow --env dishwashing --constraints {file} --total-steps 100"),
]


def run_cli(args: list[str], cwd: Path, timeout_s: float) -> tuple[int, str, float, float]:
    """Run the CLI to completion (killed with its group on timeout).

    Returns (exit code, stderr, wall seconds, CPU seconds of the child). The CPU time is what the
    command costs on an idle machine; the wall time also counts the other tests and sessions
    sharing the cores (the CLI's start-up, 1.5-3 s of imports, dominates either)."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    proc = subprocess.Popen([str(ECONMOTOR), *args], cwd=cwd, env=CHILD_ENV, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, start_new_session=True)
    try:
        _, err = proc.communicate(timeout=timeout_s)
    finally:
        kill_group(proc)
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return proc.returncode, err, wall, cpu


def kill_group(proc: subprocess.Popen) -> None:
    """SIGKILL the child's process group (the CLI and anything it started) and reap the child."""
    try:
        os.killpg(proc.pid, signal.SIGKILL)
    except ProcessLookupError:
        pass
    proc.wait(timeout=30)


@pytest.mark.parametrize(("kind", "command"), COMMANDS, ids=[f"{c.split(' --')[0]}-{k}" for k, c in COMMANDS])
def test_alias_bomb_is_one_error_line_in_seconds(tmp_path, kind, command):
    path = tmp_path / f"bomb_{kind}.yaml"
    path.write_text(BOMBS[kind])
    assert path.stat().st_size < 2_048
    args = command.format(file=path, tmp=tmp_path).split()
    args += ["--db-url", f"sqlite:///{tmp_path / 'registry.sqlite'}"] if args[0] in ("sweep", "train", "report",
                                                                                      "solve") else []
    rc, err, wall, cpu = run_cli(args, tmp_path, timeout_s=60)
    lines = [line for line in err.splitlines() if line.strip()]
    assert rc == 2, err
    assert len(lines) == 1, err
    assert lines[0].startswith("error: ") and str(path) in lines[0] and "alias" in lines[0], err
    assert cpu < 5 and wall < 30, f"{cpu:.1f} s CPU, {wall:.1f} s wall: {err}"
    print(f"{args[0]} {kind}: {wall:.2f} s wall, {cpu:.2f} s CPU")


def run_status(db: Path) -> list[str]:
    if not db.exists():
        return []
    try:
        with sqlite3.connect(db, timeout=1) as conn:
            return [row[0] for row in conn.execute("SELECT status FROM runs ORDER BY id")]
    except sqlite3.OperationalError:  # tables not created yet, or a writer holds the lock
        return []


SWEEPS = {
    "sequential": ["--task-id", "dishwashing", "--motor-backend", "dishwashing", "--max-steps", "1000000"],
    "ray": ["--task-id", "dishwashing", "--motor-backend", "dishwashing", "--max-steps", "1000000",
            "--ray", "--ray-num-cpus", "1"],
    # SIGTERM lands in the XLA compilation of the cell's training step: the command stopped in 0.3 s,
    # then the interpreter's teardown waited 46 s for the compilation and crashed (SIGSEGV)
    "mjx": ["--task-id", "hopper_courier", "--motor-backend", "mjx", "--num-envs", "8", "--max-steps", "100000"],
}


@pytest.mark.slow
@pytest.mark.parametrize("sweep", list(SWEEPS))
def test_sigterm_ends_a_long_sweep_within_10_s(tmp_path, sweep):
    pytest.importorskip({"ray": "ray", "mjx": "mujoco.mjx"}.get(sweep, "econmotor"))
    db = tmp_path / "registry.sqlite"
    args = ["sweep", *SWEEPS[sweep], "--preset", "throughput", "--db-url", f"sqlite:///{db}",
            "--output-dir", str(tmp_path / "sweep")]
    proc = subprocess.Popen([str(ECONMOTOR), *args], cwd=tmp_path, env=CHILD_ENV, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, start_new_session=True)
    try:
        deadline = time.monotonic() + 180
        while run_status(db) != ["running"]:  # the cell is recorded and training
            assert proc.poll() is None, proc.communicate()
            assert time.monotonic() < deadline, "the sweep never started its cell"
            time.sleep(0.2)
        time.sleep(3)  # well inside the cell (on Ray: inside the task)
        sent = time.monotonic()
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=10)
        took = time.monotonic() - sent
    finally:
        kill_group(proc)
    assert proc.returncode == 143, err  # 128 + SIGTERM, as a shell reports it
    assert took < 10
    assert run_status(db) == ["interrupted"]
    assert "interrupted" in err and "Resume by running the same command again" in err
    with pytest.raises(ProcessLookupError):  # nothing of its group (Ray's workers included) outlives it
        os.killpg(proc.pid, 0)
    print(f"SIGTERM to exit: {took:.2f} s ({sweep})")


HOLD_THE_LOCK = """import sqlite3, sys, time
conn = sqlite3.connect(sys.argv[1], isolation_level=None)
conn.execute("BEGIN IMMEDIATE")
print("locked", flush=True)
time.sleep(120)
"""


@pytest.mark.slow
def test_sigterm_ends_a_sweep_stuck_in_a_call_that_cannot_be_interrupted(tmp_path):
    """Another process holds the registry's write lock: the sweep waits inside SQLite (C code, where
    Python runs no signal handler). The interrupt deadline ends it anyway, 6 s after SIGTERM."""
    db = tmp_path / "registry.sqlite"
    from econmotor.store import Registry

    Registry(f"sqlite:///{db}").close()
    holder = subprocess.Popen([sys.executable, "-c", HOLD_THE_LOCK, str(db)], stdout=subprocess.PIPE, text=True,
                              start_new_session=True)
    proc = None
    try:
        assert holder.stdout.readline().strip() == "locked"
        proc = subprocess.Popen([str(ECONMOTOR), "sweep", "--task-id", "dishwashing", "--preset", "throughput",
                                 "--max-steps", "100000", "--db-url", f"sqlite:///{db}", "--output-dir",
                                 str(tmp_path / "sweep")], cwd=tmp_path, env=CHILD_ENV, stdout=subprocess.PIPE,
                                stderr=subprocess.PIPE, text=True, start_new_session=True)
        time.sleep(8)  # started up, and waiting for the lock
        assert proc.poll() is None, proc.communicate()
        sent = time.monotonic()
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=10)
        took = time.monotonic() - sent
    finally:
        for child in (proc, holder):
            if child is not None:
                kill_group(child)
    assert proc.returncode == 143, err  # 128 + SIGTERM, as a shell reports it
    assert took < 10
    assert "still busy 6 s later in a call that cannot be interrupted" in err
    assert "Resume by running the same command again" in err  # the sweep's own note, said by the watcher
    print(f"SIGTERM to exit, stuck in SQLite: {took:.2f} s")
