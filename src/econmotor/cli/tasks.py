"""``econmotor tasks``: list the task catalog with its economics."""

from __future__ import annotations

from pathlib import Path

import typer
from rich.table import Table

from econmotor.cli._app import app, console
from econmotor.tasks import load_catalog


@app.command("tasks")
def tasks_command(
    backend: str = typer.Option(None, "--backend", help="Only tasks this backend can run."),
    tasks_file: list[Path] = typer.Option([], "--tasks-file", help="Extra task catalog YAML files."),
    show: str = typer.Option(None, "--show", help="Print every economic input of one task id."),
) -> None:
    """List task ids, their unit of work and the backends that run them."""
    catalog = load_catalog(tasks_file)
    if show:
        spec = catalog.get(show)
        table = Table(title=f"{spec.task_id}: {spec.description}")
        for col in ("parameter", "value", "unit", "source"):
            table.add_column(col)
        for row in spec.economics.parameters():
            table.add_row(row["name"], f"{row['value']:g}", row["unit"], row["source"])
        console.print(table)
        console.print(f"unit of work: {spec.unit}; errors: {spec.error_definition}")
        return
    table = Table(title="econmotor task catalog")
    for col in ("task id", "unit", "backends", "human wage USD/h", "human units/h"):
        table.add_column(col)
    for task_id in catalog.ids(backend):
        spec = catalog.get(task_id)
        table.add_row(task_id, spec.unit, ", ".join(spec.backends),
                      f"{spec.economics.wage_human_usd_per_hour:g}", f"{spec.economics.mp_human_units_per_hour:g}")
    console.print(table)
