"""Running a job in .venv-holosoma from the main interpreter (the subprocess client).

:func:`run_job` writes the job (a :mod:`..job_specs` dataclass) as JSON, starts ``<venv>/bin/python -m
econmotor.motor_backend.holosoma.venv.runner job.json``, forwards ``progress`` events to the
caller's :data:`~econmotor.motor_backend.base.ProgressFn` while the job runs, collects
``message`` and ``curve`` events, keeps Holosoma's log in ``<run_dir>/<action>.log``,
and returns the ``result`` event. A failing job raises :class:`BackendError` carrying
Holosoma's own error text (its traceback or last error lines) and the log path.
"""

from __future__ import annotations

import os
import re
import subprocess
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from econmotor.errors import BackendError, ConfigError
from econmotor.motor_backend.holosoma.job_specs import HolosomaJob
from econmotor.motor_backend.holosoma.protocol import parse_line

_ANSI = re.compile(r"\x1b\[[0-9;]*[A-Za-z]")
_ERROR_MARKERS = ("Traceback (most recent call last)", "Exception occurred", "Error", "error:")


@dataclass(frozen=True)
class JobOutcome:
    """What a finished job reported."""

    result: dict[str, Any]
    messages: tuple[str, ...] = ()
    curve: tuple[dict[str, Any], ...] = ()
    log_path: str = ""
    wall_s: float = 0.0
    extra: dict[str, Any] = field(default_factory=dict)


def holosoma_error_text(lines: list[str], limit: int = 40) -> str:
    """The part of Holosoma's log that explains a failure: from the last traceback or error line."""
    clean = [_ANSI.sub("", line).rstrip() for line in lines if line.strip()]
    for i in range(len(clean) - 1, -1, -1):
        if any(marker in clean[i] for marker in _ERROR_MARKERS):
            start = i
            while start > 0 and not clean[start].startswith("Traceback") and i - start < limit:
                start -= 1
            begin = start if clean[start].startswith("Traceback") else i
            return "\n".join(clean[begin:begin + limit])
    return "\n".join(clean[-12:])


def job_environment() -> dict[str, str]:
    """The subprocess environment: no W&B, one thread, unbuffered output."""
    env = dict(os.environ)
    env.update(WANDB_MODE="disabled", PYTHONUNBUFFERED="1", LOGURU_LEVEL=env.get("LOGURU_LEVEL", "INFO"))
    env.setdefault("OMP_NUM_THREADS", "1")
    env.setdefault("MKL_NUM_THREADS", env["OMP_NUM_THREADS"])
    env.pop("PYTHONPATH", None)  # the Holosoma venv has its own econmotor (editable) and numpy 1.x
    source = Path(__file__).resolve().parents[4]  # the src/ folder this econmotor runs from
    if source.name != "site-packages" and (source / "econmotor").is_dir():
        env["PYTHONPATH"] = str(source)  # the runner runs this very econmotor (a checkout's src/, no other package)
    return env


def run_job(
    python: str | Path,
    job: HolosomaJob,
    run_dir: str | Path,
    progress: Callable[[str, float, float], None],
    timeout_s: float | None = None,
) -> JobOutcome:
    """Run one job (see the module docstring); its ``log_name`` names the job and log files."""
    import time

    run_dir = Path(run_dir)
    run_dir.mkdir(parents=True, exist_ok=True)
    action = job.action
    job_path = run_dir / f"{job.log_name}_job.json"
    job_path.write_text(job.to_json(), encoding="utf-8")
    log_path = run_dir / f"{job.log_name}.log"
    cmd = [str(python), "-u", "-m", "econmotor.motor_backend.holosoma.venv.runner", str(job_path)]
    tail: deque[str] = deque(maxlen=400)
    messages: list[str] = []
    curve: list[dict[str, Any]] = []
    result: dict[str, Any] | None = None
    error: dict[str, Any] | None = None
    start = time.monotonic()
    with open(log_path, "w", encoding="utf-8") as log:
        proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                                env=job_environment(), cwd=str(run_dir), bufsize=1, errors="replace")
        try:
            assert proc.stdout is not None
            for line in proc.stdout:
                log.write(line)
                event = parse_line(line)
                if event is None:
                    tail.append(line)
                elif event["event"] == "progress":
                    progress(str(event["label"]), float(event["done"]), float(event["total"]))
                elif event["event"] == "message":
                    messages.append(str(event["text"]))
                    progress(f"holosoma: {event['text']}", 1.0, 1.0)
                elif event["event"] == "curve":
                    curve.append(event)
                elif event["event"] == "result":
                    result = {k: v for k, v in event.items() if k != "event"}
                elif event["event"] == "error":
                    error = event
                if timeout_s is not None and time.monotonic() - start > timeout_s:
                    proc.kill()
                    raise BackendError(f"Holosoma {action} job exceeded {timeout_s:.0f} s; log: {log_path}")
            rc = proc.wait()
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.wait()
    if rc != 0 or result is None:
        raise_failure(action, rc, error, list(tail), log_path)
    return JobOutcome(result, tuple(messages), tuple(curve), str(log_path), time.monotonic() - start)


def raise_failure(action: str, rc: int, error: dict[str, Any] | None, tail: list[str], log_path: Path) -> None:
    """The error of a failed job: its ConfigError (the job's bad input) as the same ConfigError here, else a
    BackendError with the job's error or the log's Holosoma error and the log's path."""
    if error is not None and error.get("config_error"):
        raise ConfigError(*error["config_error"])
    text = f"{error['text']}\n{error.get('traceback', '')}".strip() if error is not None else holosoma_error_text(tail)
    raise BackendError(f"Holosoma {action} failed (exit code {rc}):\n{text}\nfull log: {log_path}")


