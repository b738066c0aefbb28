"""The line protocol between :mod:`.venv.runner` (in .venv-holosoma) and :mod:`.host.jobs` (main venv).

The runner prints one JSON object per line after :data:`PREFIX` on stdout; every other
line is Holosoma's own log. Events: ``progress`` (label, done, total), ``message``
(text: an adaptation or note for the user), ``curve`` (one training iteration:
iteration, timesteps, mean_return, econ: {term: value}), ``result`` (the job's
outcome), ``error`` (text, traceback: a failure in econmotor's runner code).
"""

from __future__ import annotations

import json
import sys
from typing import Any

PREFIX = "@@econmotor "


def emit(event: str, **data: Any) -> None:
    """Print one protocol line and flush (the parent reads it while the job runs)."""
    # Leading newline: Holosoma's rich panels do not always end their last line.
    sys.stdout.write("\n" + PREFIX + json.dumps({"event": event, **data}, default=str) + "\n")
    sys.stdout.flush()


def parse_line(line: str) -> dict[str, Any] | None:
    """The event of a protocol line, or ``None`` for a Holosoma log line."""
    start = line.find(PREFIX)
    if start < 0:
        return None
    try:
        event = json.loads(line[start + len(PREFIX):])
    except json.JSONDecodeError:
        return None
    return event if isinstance(event, dict) and "event" in event else None
