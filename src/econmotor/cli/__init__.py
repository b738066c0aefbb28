"""econmotor's command line: one Typer app (``econmotor --help``).

Every module in this package registers its commands on :data:`app` when imported.
"""

from __future__ import annotations

import importlib
import logging
import pkgutil
import sys

import typer
from rich.markup import escape
from typer._click.exceptions import ClickException  # typer vendors click

from econmotor.cli._app import app, err_console
from econmotor.cli._interrupts import (
    CommandInterrupted,
    InterruptGuard,
    end_interrupted_process,
    interrupted_exit_code,
    was_interrupted,
)
from econmotor.errors import EconmotorError


class _WarningLine(logging.Handler):
    """Library warnings (logger ``econmotor``, e.g. a damaged checkpoint skipped) as one stderr line."""

    def emit(self, record: logging.LogRecord) -> None:
        err_console.print(f"[yellow]warning:[/] {escape(record.getMessage())}", highlight=False, soft_wrap=True)


_library_log = logging.getLogger("econmotor")
if not any(isinstance(h, _WarningLine) for h in _library_log.handlers):
    _library_log.addHandler(_WarningLine(logging.WARNING))
    _library_log.propagate = False

for _module in pkgutil.iter_modules(__path__):
    if not _module.name.startswith("_"):
        importlib.import_module(f"{__name__}.{_module.name}")


def main(argv: list[str] | None = None) -> int:
    """Run the CLI; econmotor errors print as one clear line and exit with status 2.

    SIGINT and SIGTERM raise KeyboardInterrupt for the whole command, with a deadline
    (:class:`econmotor.cli._interrupts.InterruptGuard`)."""
    guard = InterruptGuard()
    try:
        return _run(argv)
    finally:
        guard.close()


def _run(argv: list[str] | None) -> int:
    try:
        rc = app(args=argv, standalone_mode=False)
    except EconmotorError as exc:
        err_console.print(f"[bold red]error:[/] {escape(str(exc))}", highlight=False, soft_wrap=True)
        return 2
    except typer.Abort:  # a command that printed its own note of the interrupt (what it kept, how to resume)
        if not was_interrupted():
            err_console.print("[yellow]aborted[/]")
        return interrupted_exit_code()
    except (KeyboardInterrupt, CommandInterrupted) as exc:  # a command without its own note
        err_console.print(f"[yellow]interrupted[/] ({exc or 'Ctrl-C'}): nothing further was written", highlight=False)
        return interrupted_exit_code()
    except typer.Exit as exc:
        return exc.exit_code
    except SystemExit as exc:  # click usage errors
        return int(exc.code or 0)
    except ClickException as exc:  # usage errors: one line naming the flag, no traceback
        message = " ".join(exc.format_message().split())
        group = getattr(getattr(exc, "ctx", None), "command", None)  # the command group that was asked
        if message.startswith("No such command") and "Did you mean" not in message and hasattr(group, "commands"):
            message += f" Commands: {', '.join(sorted(group.commands))}."
        err_console.print(f"[bold red]error:[/] {escape(message)}", highlight=False, soft_wrap=True)
        return exc.exit_code
    # with standalone_mode=False click returns typer.Exit's code instead of raising it
    return rc if isinstance(rc, int) else 0


def entrypoint() -> None:
    exit_code = main()
    if was_interrupted():
        end_interrupted_process(exit_code)
    sys.exit(exit_code)
