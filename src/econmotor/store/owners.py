"""Who owns a run, and what becomes of a ``running`` run whose owner is gone.

A run records its owner when it starts (:func:`run_owner`: host, pid and the process's start time,
in ``config["owner"]``; the start time tells a reused pid apart). Two things follow from it:

- **abandoned runs** (:func:`mark_abandoned_runs`, on opening a registry): a ``running`` run whose
  owner process on this host is gone (a kill -9, a power cut) is marked ``abandoned``, so no dead run
  stays ``running``. A run of another host, or of an owner not recorded, is never guessed dead.
- **this process's last word** (:func:`interrupt_own_runs`): a process that must end now marks its
  own ``running`` runs ``interrupted`` in every registry it started runs in.
"""

from __future__ import annotations

import os
import socket
from pathlib import Path
from typing import Any

from sqlalchemy import select

from econmotor.errors import RegistryError
from econmotor.store.database import RegistryDatabase
from econmotor.store.models import RunRow, utc_now

#: registries this process has started runs in (for :func:`interrupt_own_runs`).
_URLS_WITH_OWN_RUNS: set[str] = set()


def remember_own_runs(url: str) -> None:
    """Note that this process started a run in the registry at ``url`` (for :func:`interrupt_own_runs`)."""
    _URLS_WITH_OWN_RUNS.add(url)


def run_owner() -> dict[str, Any]:
    """Who runs this process: host, pid and the process start time (tells a reused pid apart)."""
    pid = os.getpid()
    return {"host": socket.gethostname(), "pid": pid, "start": _process_start(pid)}


def mark_abandoned_runs(db: RegistryDatabase) -> list[int]:
    """Mark ``running`` runs whose owner process on this host is gone as ``abandoned``; returns their ids."""
    host = socket.gethostname()
    with db._read() as s:
        running = s.execute(select(RunRow.id, RunRow.config).where(RunRow.status == "running")).all()
    gone = [run_id for run_id, config in running
            if isinstance(owner := (config or {}).get("owner"), dict) and owner.get("host") == host
            and not _process_alive(owner.get("pid"), owner.get("start"))]
    if gone:
        with db._write() as s:
            for run_id in gone:
                run = s.get(RunRow, run_id)
                if run is not None and run.status == "running":
                    owner = run.config["owner"]
                    run.status, run.finished_at = "abandoned", utc_now()
                    run.error = (f"abandoned: its process {owner.get('pid')} on {host} ended without "
                                 "recording an outcome (killed?)")
    return gone


def interrupt_own_runs(reason: str, busy_timeout_s: float = 2.0) -> list[int]:
    """Mark this process's ``running`` runs ``interrupted`` (error ``reason``) in every registry it
    started runs in; returns their ids.

    The last word of a process that must end now (the CLI's interrupt deadline, when the main thread
    is stuck in a call that cannot be interrupted): a connection of its own with a short busy
    timeout, so a transaction left open by the main thread cannot hold it up. Each registry is opened
    as ``Registry(url, create=False)`` opens it, abandoned runs marked first.
    """
    me = run_owner()
    marked: list[int] = []
    for url in sorted(_URLS_WITH_OWN_RUNS):
        try:
            registry = RegistryDatabase(url, create=False, busy_timeout_s=busy_timeout_s)
            mark_abandoned_runs(registry)
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


def _process_start(pid: int) -> str | None:
    """The start time of process ``pid`` (clock ticks since boot, from /proc), or None where unknown."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return None
    return stat.rsplit(")", 1)[-1].split()[19]


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
