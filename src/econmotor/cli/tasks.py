"""``econmotor tasks``: list the task catalog with its economics."""

from __future__ import annotations

from pathlib import Path

import typer
from rich.table import Table

from econmotor.cli._app import app, console
from econmotor.motor_backend.factory import load_checked_catalog


@app.command("tasks")
def tasks_command(
    backend: str = typer.Option(None, "--backend", help="Only tasks this backend can run."),
    tasks_file: list[Path] = typer.Option([], "--tasks-file", help="Extra task catalog YAML files."),
    show: str = typer.Option(None, "--show", help="Print every economic input of one task id."),
) -> None:
    """List task ids, their unit of work and the backends that run them."""
    catalog = load_checked_catalog(tasks_file)
    if show:
        spec = catalog.get(show)
        table = Table(title=f"{spec.task_id}: {spec.description}")
        rows = spec.economics.parameters()
        # names whole while the terminal allows (a fixed width is not shrunk first), folded past that
        table.add_column("parameter", width=max([len("parameter"), *(len(row["name"]) for row in rows)]),
                         overflow="fold")
        table.add_column("value", justify="right", no_wrap=True)
        table.add_column("unit", overflow="fold")
        table.add_column("source", overflow="fold", ratio=1)
        for row in rows:
            table.add_row(row["name"], f"{row['value']:g}", row["unit"], row["source"])
        console.print(table)
        console.print(f"unit of work: {spec.unit}; errors: {spec.error_definition}", highlight=False)
        acc = spec.acceptance
        console.print(f"deployable when the {acc.error_name} rate's 95% upper bound <= {acc.max_error_rate:g} "
                      f"({acc.sources.get('max_error_rate', '')}) and throughput's 95% lower bound >= "
                      f"{acc.min_units_per_hour:g} units/h ({acc.sources.get('min_units_per_hour', '')})",
                      highlight=False)
        return
    table = Table(title="econmotor task catalog")
    ids = catalog.ids(backend)
    # ids are typed by users: whole while the terminal allows (a fixed width is not shrunk first), never cut
    table.add_column("task id", width=max([len("task id"), *map(len, ids)]), overflow="fold")
    table.add_column("unit of work", overflow="fold")
    table.add_column("backends", overflow="fold")
    for col in ("human\nUSD/h", "human\nunits/h"):  # two lines: the room goes to the unit of work
        table.add_column(col, justify="right", overflow="fold")
    for task_id in ids:
        spec = catalog.get(task_id)
        table.add_row(task_id, spec.unit, ", ".join(spec.backends),
                      f"{spec.economics.wage_human_usd_per_hour:g}", f"{spec.economics.mp_human_units_per_hour:g}")
    console.print(table)
