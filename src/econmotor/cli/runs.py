"""A training request run from the command line (``train``, ``report``, ``demo``): progress bars, and on
Ctrl-C (or the interrupt deadline) one note saying what the run kept and how to go on. Registers no command.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import typer

from econmotor.cli._app import err_console, progress_bars
from econmotor.cli._interrupts import set_deadline_note
from econmotor.motor_backend.factory import backend_class
from econmotor.recording import TrainRequest, train_and_record
from econmotor.store.registry import Registry


def interrupted_note(backend: str, task: str, run_dir: Path, max_steps: int, command: str = "train",
                     init_policy: str | None = None) -> str:
    """What an interrupted training run kept and how to go on: ``--resume`` from its newest checkpoint (which
    holds the fine-tuned weights, so no ``--init-policy``), else ``command`` again from ``init_policy``."""
    checkpoints = backend_class(backend).checkpoints(run_dir)
    if checkpoints:
        return (f"the training run was recorded as interrupted. Kept: {len(checkpoints)} checkpoint(s) in "
                f"{run_dir}/checkpoints (newest {checkpoints[-1].name}). Resume with: econmotor train --task-id "
                f"{task} --motor-backend {backend} --output-dir {run_dir} --max-steps {max_steps} --resume")
    kept = f"the partial run directory {run_dir}" if run_dir.exists() else "no files"
    return (f"the training run was recorded as interrupted. Kept: {kept}; no checkpoint to resume from, so start "
            f"again: econmotor {command} --task-id {task} --motor-backend {backend} --max-steps {max_steps}"
            + (f" --init-policy {init_policy}" if init_policy else ""))


def train_with_bars(request: TrainRequest, backend: Any, url: str,
                    note: Callable[[], str]) -> tuple[Registry, int, int | None]:
    """:func:`~econmotor.recording.train_and_record` under progress bars; returns ``(registry, train run id,
    eval run id or None)``. ``note()`` says what an interruption keeps: printed on Ctrl-C (then ``typer.Abort``)
    and by the interrupt deadline."""
    set_deadline_note(note)
    try:
        with progress_bars() as progress:
            return train_and_record(request, backend, lambda: Registry(url), progress)
    except KeyboardInterrupt:
        err_console.print(f"[yellow]interrupted[/]: {note()}", highlight=False)
        raise typer.Abort from None
