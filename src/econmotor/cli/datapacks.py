"""``econmotor datapacks validate``: check datapack YAML files.

Besides the generic schema, each pack's ``domain_randomization`` and ``curriculum``
are checked by the backend that will use them (``--motor-backend``), or, without the
flag, by every backend: a pack passes if at least one backend accepts it, so a range
no backend can use fails here rather than later in ``report``.
"""

from __future__ import annotations

from pathlib import Path

import typer
from rich.console import Console
from rich.table import Table

from econmotor.cli._app import console, datapacks_app, fits_unwrapped
from econmotor.cli.validation import check_choice
from econmotor.config.datapacks import DatapackConfig, load_datapack_configs
from econmotor.errors import ConfigError
from econmotor.motor_backend.factory import backend_class, known_backends

COLUMNS = ("id", "clips", "domain_randomization", "curriculum", "backends", "file")


def check_for_backends(pack: DatapackConfig, backend: str | None = None) -> list[str]:
    """The backends that accept ``pack`` (only ``backend`` when given); none: its ConfigError."""
    names = [backend] if backend else known_backends()
    accepted, errors = [], []
    for name in names:
        try:
            backend_class(name).check_datapack(pack, pack.source)
            accepted.append(name)
        except ConfigError as exc:
            errors.append(exc)
    if not accepted:
        # the most specific complaint: a problem of the pack itself (a bad value, a missing clip file)
        # beats a key some backend does not support, which beats an unknown key
        raise min(errors, key=lambda e: (e.detail.startswith("unknown key"), "not supported by" in e.detail))
    return accepted


@datapacks_app.command("validate")
def validate_command(
    paths: list[Path] = typer.Argument(..., help="Datapack YAML files."),
    motor_backend: str = typer.Option(None, "--motor-backend", help="Check the randomization for this backend "
                                      f"({', '.join(known_backends())}; default: any of them)."),
) -> None:
    """Validate datapacks and show what each one sets."""
    check_choice("--motor-backend", motor_backend, known_backends())
    rows = []
    for pack in load_datapack_configs(paths):
        backends = check_for_backends(pack, motor_backend)
        rows.append((pack.id, str(len(pack.motion_clips)), ", ".join(pack.domain_randomization) or "-",
                     ", ".join(pack.curriculum) or "-", ", ".join(backends), str(pack.source)))
    console.print(datapacks_table(rows, console))


def datapacks_table(rows: list[tuple[str, ...]], out: Console) -> Table:
    """One row per pack where that fits ``out``'s width unwrapped, else a field / value section per pack.
    Cells fold, never cut: ids, keys and paths are copied by users."""
    table = Table(title="datapacks")
    for col in COLUMNS:
        table.add_column(col, overflow="fold")
    for row in rows:
        table.add_row(*row)
    if fits_unwrapped(table, out):
        return table
    table = Table(title="datapacks")
    table.add_column("field", width=max(map(len, COLUMNS)), overflow="fold")  # kept whole while it can be
    table.add_column("value", overflow="fold")
    for row in rows:
        for i, (field, value) in enumerate(zip(COLUMNS, row, strict=True)):
            table.add_row(field, value, style="bold" if i == 0 else None, end_section=i == len(COLUMNS) - 1)
    return table
