"""A sweep's local Ray, started in a process of its own so that the sweep's process never forks.

``ray.init()`` without an address starts Ray's processes (GCS, raylet, ...) from the calling process with
``subprocess.Popen(preexec_fn=...)``: Python forks and runs code in the child before ``exec``. Once JAX (the
mjx backend asks ``jax.default_backend()`` for a cell's resources) or torch has started threads, such a fork
can deadlock; JAX warns "os.fork() was called ... will likely lead to a deadlock". :func:`local_ray_head`
instead starts this module as a program (``fork_exec``, no Python between the fork and the ``exec``); it
calls ``ray.init`` there, writes the cluster's address on one line and holds Ray until its standard input
closes, then shuts it down. The sweep connects with ``ray.init(address=...)``, which starts no process.
The head ignores SIGINT and SIGTERM once Ray runs, so the sweep decides when Ray stops, however the sweep
ends: closing the pipe (or the sweep's end, which closes it) stops it.
"""

from __future__ import annotations

import json
import os
import select
import signal
import subprocess
import sys
import time
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from typing import Any

from econmotor.errors import BackendError

#: the line the head writes once Ray runs, before the address
ADDRESS_PREFIX = "econmotor-ray-head: "
#: seconds the head has to start Ray, and to shut it down once asked
START_S = 120.0
STOP_S = 10.0


@contextmanager
def local_ray_head(init_kwargs: Mapping[str, Any]) -> Iterator[str]:
    """A local Ray cluster started by ``ray.init(**init_kwargs)`` in a head process (module docstring);
    yields its address for ``ray.init(address=...)`` and shuts the cluster down on leaving."""
    head = subprocess.Popen([sys.executable, "-m", __name__, json.dumps(dict(init_kwargs))],
                            stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    try:
        address = _read_address(head)
        _authenticate_as_a_local_driver()
        yield address
    finally:
        _stop(head)


def _authenticate_as_a_local_driver() -> None:
    """Ray (2.5x) turns token authentication on for a new local cluster (the head's ``ray.init()``, which
    writes the token where Ray keeps it), and for a connection only when it finds a local cluster itself
    (``address="auto"``), not for a given address: this process does here what "auto" would."""
    try:
        from ray._private.authentication.authentication_token_setup import (
            maybe_enable_token_auth_if_token_available,
        )
    except ImportError:  # a Ray without token authentication
        return
    maybe_enable_token_auth_if_token_available(warn_if_disabled=False)


def _read_address(head: subprocess.Popen) -> str:
    """The address the head writes once Ray runs; a BackendError if it ends or takes over :data:`START_S`."""
    assert head.stdout is not None
    deadline = time.monotonic() + START_S
    while (left := deadline - time.monotonic()) > 0:
        if not select.select([head.stdout], [], [], left)[0]:
            break
        line = head.stdout.readline()
        if not line:
            raise BackendError(f"Ray's local head ended before Ray started (exit code {head.wait()}); "
                               "its error is above")
        if line.startswith(ADDRESS_PREFIX):
            return line[len(ADDRESS_PREFIX):].strip()
    raise BackendError(f"Ray's local head did not start Ray within {START_S:.0f} s")


def _stop(head: subprocess.Popen) -> None:
    """Close the head's input (it shuts Ray down and ends); kill it if it has not ended :data:`STOP_S` later."""
    for stream in (head.stdin, head.stdout):
        if stream is not None:
            stream.close()
    try:
        head.wait(timeout=STOP_S)
    except subprocess.TimeoutExpired:
        head.kill()
        head.wait()


def serve(init_kwargs: Mapping[str, Any]) -> None:
    """The head: start Ray, say its address, hold it until standard input closes, shut it down. Only the
    address goes to standard output (the pipe): whatever Ray or its processes print goes to standard error."""
    address_out = os.fdopen(os.dup(sys.stdout.fileno()), "w")
    os.dup2(sys.stderr.fileno(), sys.stdout.fileno())
    import ray

    context = ray.init(**init_kwargs)
    try:
        for signum in (signal.SIGINT, signal.SIGTERM):  # the sweep decides when Ray stops (module docstring)
            signal.signal(signum, signal.SIG_IGN)
        with address_out:
            address_out.write(f"{ADDRESS_PREFIX}{context.address_info['gcs_address']}\n")
        sys.stdin.read()
    finally:
        ray.shutdown()


if __name__ == "__main__":
    serve(json.loads(sys.argv[1]))
