"""Hostile input through the real command line (``.venv/bin/econmotor`` in a child process).

An alias bomb ("billion laughs": 2 KB on disk, 9^9 strings once its aliases are written out)
as a datapack, a task file, an objective or a constraint set: every command that reads that
kind of YAML exits 2 with one line naming the file (the refusal never writes the aliases out:
tests/unit/config/test_yaml_aliases.py counts its work; the child's times are printed, not asserted). And
SIGTERM during a long sweep (in this process, and on Ray) ends it through KeyboardInterrupt, before the
interrupt deadline, the cell in flight recorded as ``interrupted``; a sweep stuck in a call that cannot be
interrupted is ended by the deadline. Every child runs in its own process group, killed and reaped in
``finally``. Speed lives in benchmarks/: nothing here asserts a wall-clock time.
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
def test_alias_bomb_is_one_error_line(tmp_path, kind, command):
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
def test_sigterm_ends_a_long_sweep_before_the_interrupt_deadline(tmp_path, sweep):
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
        _, err = proc.communicate(timeout=120)  # a hang guard, not the claim
        took = time.monotonic() - sent
    finally:
        kill_group(proc)
    assert proc.returncode == 143, err  # 128 + SIGTERM, as a shell reports it
    assert "still busy" not in err  # ended by KeyboardInterrupt, not by the deadline 6 s after the signal
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


#: sleep system calls (x86_64, aarch64): SQLite's busy handler sleeps between tries for a lock
SLEEP_SYSCALLS = {"x86_64": {35, 230}, "aarch64": {101, 115}}


def wait_inside_sqlite(proc: subprocess.Popen, db: Path) -> None:
    """Until ``proc`` has ``db`` open and its main thread sleeps in a system call: waiting for the lock inside
    SQLite's busy handler (nothing else in the sweep sleeps after it opens the registry)."""
    sleeps = SLEEP_SYSCALLS.get(os.uname().machine)
    if sleeps is None:
        pytest.skip(f"no sleep system call numbers for {os.uname().machine}")
    deadline, target, fds = time.monotonic() + 180, os.path.realpath(db), f"/proc/{proc.pid}/fd"  # a hang guard
    while True:
        assert proc.poll() is None, proc.communicate()
        assert time.monotonic() < deadline, "the sweep never waited for the registry's lock"
        try:
            opened = any(os.readlink(f"{fds}/{fd}") == target for fd in os.listdir(fds))
            call = Path(f"/proc/{proc.pid}/syscall").read_text().split()[0]
        except OSError:  # a file descriptor closed while listed
            continue
        if opened and call.isdigit() and int(call) in sleeps:
            return
        time.sleep(0.05)


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
        wait_inside_sqlite(proc, db)
        sent = time.monotonic()
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=120)  # a hang guard, not the claim
        took = time.monotonic() - sent
    finally:
        for child in (proc, holder):
            if child is not None:
                kill_group(child)
    assert proc.returncode == 143, err  # 128 + SIGTERM, as a shell reports it
    assert "still busy 6 s later in a call that cannot be interrupted" in err
    assert "Resume by running the same command again" in err  # the sweep's own note, said by the watcher
    print(f"SIGTERM to exit, stuck in SQLite: {took:.2f} s")
