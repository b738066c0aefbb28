"""The one Typer app and the rendering helpers every command module shares.

Command modules live beside this file (``report.py``, ``shadow.py``, ...); each
imports ``app`` (or a sub-app such as ``datapacks_app``) from here and decorates its
commands. ``econmotor.cli`` imports every module of the package, so adding a command
is adding a file.
"""

from __future__ import annotations

import contextlib
import os
import sys
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

import typer
from rich.console import Console
from rich.measure import Measurement
from rich.progress import (
    BarColumn,
    MofNCompleteColumn,
    Progress,
    ProgressColumn,
    TextColumn,
    TimeElapsedColumn,
    TimeRemainingColumn,
)
from rich.table import Table
from rich.text import Text

from econmotor.cli._interrupts import InterruptibleGroup

app = typer.Typer(
    cls=InterruptibleGroup,  # a command's KeyboardInterrupt reaches main(), which exits 143 on SIGTERM
    name="econmotor",
    help="Train robot motor policies for economic objectives and price the labour they deliver.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)
datapacks_app = typer.Typer(help="Validate datapacks; record motion clips.", no_args_is_help=True)
app.add_typer(datapacks_app, name="datapacks")

# Messages are soft-wrapped (one line each) when the stream is not a terminal, so piped output and
# logs keep whole lines; tables still lay out to the width (COLUMNS, else 80 when not a terminal).
console = Console(soft_wrap=not sys.stdout.isatty())
err_console = Console(stderr=True, soft_wrap=not sys.stderr.isatty())


def set_cpu_threads() -> None:
    """One torch thread per process unless the user set OMP_NUM_THREADS (30x faster on 2 cores)."""
    threads = int(os.environ.setdefault("OMP_NUM_THREADS", "1"))
    os.environ.setdefault("MKL_NUM_THREADS", str(threads))
    try:
        import torch

        torch.set_num_threads(threads)
    except ImportError:  # torch-free commands
        pass


#: progress labels longer than this are messages: printed whole above the bars instead of cut to fit one.
MAX_BAR_LABEL = 40
def make_backend(name: str, task_files: Sequence[str | Path] = (), **options: Any) -> Any:
    """Construct motor backend ``name`` at the edge: ``task_files``, the options the backend takes from
    environment variables (its ``environment_options``, read here and nowhere inside it), then ``options``."""
    from econmotor.motor_backend.factory import environment_options, make_motor_backend

    return make_motor_backend(name, task_files=list(task_files), **{**environment_options(name, os.environ),
                                                                       **options})


def announce_device(backend: Any, doing: str = "training") -> None:
    """Say which device a backend computes on, for backends that declare one (e.g. a JAX device)."""
    described = backend.device_description()
    if described:
        err_console.print(f"{backend.name}: {doing} on {described}", highlight=False)


def announce_num_envs(backend: Any, task_id: str, num_envs: int | None) -> None:
    """Say how the backend adapts a ``--num-envs`` request on this machine (e.g. capped on a CPU)."""
    note = backend.num_envs_note(task_id, int(num_envs or 0))
    if note:
        err_console.print(f"[yellow]note[/]: {note}", highlight=False, soft_wrap=True)


class RateColumn(ProgressColumn):
    """Units per second of a bar (env steps/s while training, episodes/s while evaluating)."""

    def render(self, task) -> Text:
        speed = task.finished_speed or task.speed
        return Text(f"{speed:,.0f}/s" if speed else "", style="progress.data.speed")


def fits_unwrapped(table: Table, out: Console) -> bool:
    """Whether ``table`` at its natural width (every cell on one line) fits ``out``'s width."""
    return Measurement.get(out, out.options.update_width(10_000), table).maximum <= out.width


@contextlib.contextmanager
def progress_bars() -> Iterator:
    """Yield a ``ProgressFn`` that draws one rich bar per label."""
    progress = Progress(
        TextColumn("[bold]{task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        RateColumn(),
        TimeElapsedColumn(),
        TimeRemainingColumn(),
        console=err_console,
        transient=False,
    )
    tasks: dict[str, int] = {}
    said: set[str] = set()

    def update(label: str, completed: float, total: float) -> None:
        key = label.split(" · ", 1)[0]  # "train · @50k: deployable": the train bar, showing the latest verdict
        if len(key) > MAX_BAR_LABEL:  # a message (e.g. an adaptation), not a bar: printed whole, once
            if label not in said:
                said.add(label)
                progress.console.print(label, highlight=False, soft_wrap=True)
            return
        if key not in tasks:
            if not tasks:
                progress.start()
            tasks[key] = progress.add_task(label, total=total)
        progress.update(tasks[key], completed=completed, total=total, description=label)

    try:
        yield update
    finally:  # started with the first bar: a command that fails before one leaves no blank line
        if tasks:
            progress.stop()
