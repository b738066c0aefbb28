"""``econmotor datapacks validate``: check datapack YAML files."""

from __future__ import annotations

from pathlib import Path

import typer
from rich.table import Table

from econmotor.cli._app import console, datapacks_app
from econmotor.motor_backend.datapacks import load_datapack_configs


@datapacks_app.command("validate")
def validate_command(paths: list[Path] = typer.Argument(..., help="Datapack YAML files.")) -> None:
    """Validate datapacks and show what each one sets."""
    table = Table(title="datapacks")
    for col in ("id", "clips", "domain_randomization", "curriculum", "file"):
        table.add_column(col)
    for pack in load_datapack_configs(paths):
        table.add_row(pack.id, str(len(pack.motion_clips)), ", ".join(pack.domain_randomization) or "-",
                      ", ".join(pack.curriculum) or "-", pack.source)
    console.print(table)
