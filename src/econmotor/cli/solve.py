"""``econmotor solve``: the objective surface over recorded episodes.

Reads episodes from the registry (filters: task, backend, datapacks, objective) or
from JSONL exports, scores every run under every objective and constraint set, and
writes ``objective_surface.json``, ``objective_surface.md`` and ``pareto_front.png``.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import typer
from rich.table import Table

from econmotor.analysis.episode_table import EpisodeTable, read_episodes_jsonl, write_episodes_jsonl
from econmotor.analysis.objective_surface import objectives_from_options, solve_objective_surface
from econmotor.analysis.surface_report import surface_cells, write_surface_outputs
from econmotor.cli._app import app, console, err_console
from econmotor.cli.options import open_registry, split_ids
from econmotor.cli.validation import (
    FLAG_RULES,
    MAX_SOLVE_OBJECTIVES,
    check_choice,
    check_db_url,
    check_flags,
    check_input_files,
    check_output_dir,
    check_output_file,
    check_size,
    note_abandoned,
    simplex_size,
)
from econmotor.economics.uncertainty import counted
from econmotor.errors import ConfigError
from econmotor.motor_backend.run_dir import utc_stamp
from econmotor.rl.shadow_log import EPISODES_FILE
from econmotor.valuation import ConstraintSet, load_constraint_sets

REFERENCE_KEYS = {"mpl": "mpl_units_per_hour", "energy": "energy_wh_per_unit", "error": "error_rate",
                  "risk": "risk_score"}


def parse_reference(values: list[str]) -> dict[str, float]:
    """``["energy=3", "mpl=0"]`` -> criterion -> bound."""
    out = {}
    for item in values:
        key, _, value = item.partition("=")
        name = REFERENCE_KEYS.get(key.strip(), key.strip())
        if name not in REFERENCE_KEYS.values() or not value:
            raise ConfigError("--reference-point", key, f"expected KEY=VALUE, got {item!r}", REFERENCE_KEYS)
        try:
            out[name] = float(value)
        except ValueError:
            raise ConfigError("--reference-point", key, f"not a number: {value!r}") from None
        FLAG_RULES["--reference-point"].check(f"--reference-point {key.strip()}", out[name])
    return out


#: where each solve writes its outputs (a folder of its own) unless --output-dir says otherwise
SURFACES_DIR = Path("runs/objective_surface")


def episode_files(paths: list[Path]) -> list[Path]:
    """``--episodes-jsonl``'s files: a file as given, a folder as every shadow run's
    ``shadow_episodes.jsonl`` below it (sorted); a folder without one is an error."""
    files: list[Path] = []
    for path in paths:
        found = sorted(path.rglob(EPISODES_FILE)) if path.is_dir() else [path]
        if not found:
            raise ConfigError("--episodes-jsonl", None, f"{path} is a folder with no {EPISODES_FILE} below it "
                                                        "(a shadow run writes one into its run directory)")
        files += found
    check_input_files("--episodes-jsonl", files)
    return files


@app.command("solve")
def solve_command(
    episodes_jsonl: list[Path] = typer.Option([], "--episodes-jsonl", help="Read episodes from JSONL exports "
                                              "instead of the registry (repeatable); a folder reads every "
                                              f"{EPISODES_FILE} below it (e.g. runs/shadow: all shadow runs)."),
    db_url: str = typer.Option(None, "--db-url", help="Registry URL (default $ECONMOTOR_DB_URL or "
                               "./.econmotor/registry.sqlite)."),
    task_id: str = typer.Option(None, "--task-id", help="Only runs of this task."),
    motor_backend: str = typer.Option(None, "--motor-backend", help="Only runs of this backend."),
    datapacks: list[str] = typer.Option([], "--datapacks", help="Only runs that used all these datapack ids."),
    objective: str = typer.Option(None, "--objective", help="Only runs trained under this objective name."),
    run_kind: str = typer.Option(None, "--run-kind", help="Only 'train' or 'eval' runs (default both)."),
    constraints: Path = typer.Option(None, "--constraints", help="Constraint-sets YAML "
                                     "(e.g. configs/constraints/default.yaml); default: unconstrained."),
    preset: list[str] = typer.Option([], "--preset", help="Objective presets (comma list or repeated); "
                                     "all six when no objective is given."),
    vector: list[str] = typer.Option([], "--vector", help="Objective vector 'mpl,error,energy,safety,novelty'."),
    grid: int = typer.Option(0, "--grid", help="Add every simplex weight vector with step 1/GRID."),
    include_novelty: bool = typer.Option(False, "--include-novelty", help="Let the grid weight novelty too."),
    energy_term: str = typer.Option("wh", "--energy-term", help="J's energy term: wh (-Wh, the default) or usd "
                                    "(priced at the task's electricity price)."),
    reference_point: list[str] = typer.Option([], "--reference-point", help="Hypervolume bound, e.g. "
                                              "energy=5 (keys: mpl, energy, error, risk)."),
    output_dir: Path = typer.Option(None, "--output-dir", help="Where outputs go (default: a new "
                                    f"{SURFACES_DIR}/<UTC time>-<pid>, so a solve never overwrites another's)."),
    export_jsonl: Path = typer.Option(None, "--export-jsonl", help="Also write the episodes read as JSONL."),
) -> None:
    """Which objective should a customer buy under which constraints? Re-score recorded episodes."""
    check_flags(grid=grid)
    check_size("--grid", "objectives", simplex_size(grid, include_novelty), MAX_SOLVE_OBJECTIVES)
    check_choice("--run-kind", run_kind, ("train", "eval"))
    episodes_jsonl = episode_files(episodes_jsonl)
    if constraints:
        check_input_files("--constraints", [constraints])
    check_output_dir("--output-dir", output_dir)
    if output_dir is None:
        output_dir = SURFACES_DIR / f"{utc_stamp()}-{os.getpid()}"
    check_output_file("--export-jsonl", export_jsonl)
    if not episodes_jsonl:
        db_url = check_db_url(db_url, create=False)
    sets = load_constraint_sets(constraints) if constraints else [ConstraintSet(name="unconstrained")]
    objectives = objectives_from_options(preset, vector, grid, include_novelty, energy_term)
    reference = parse_reference(reference_point)
    if episodes_jsonl:
        table, source = episodes_from_files(episodes_jsonl)
    else:
        table, source = episodes_from_db(db_url, task_id, motor_backend, split_ids(datapacks), objective, run_kind)
    if export_jsonl:
        err_console.print(f"episodes written to {write_episodes_jsonl(table, export_jsonl)}")
    surface = solve_objective_surface(table, objectives, sets)
    files = write_surface_outputs(surface, output_dir, reference,
                                  {**source, "constraints": str(constraints) if constraints else None})
    _print_summary(surface, files)


def _print_summary(surface, files) -> None:
    """Objectives x constraint sets, each cell 'best valid run (J)'; grid objectives only in the files."""
    import json

    document = json.loads(files["json"].read_text())
    shown = [o.name for o in surface.objectives if o.kind != "grid"][:12]
    # one row per (objective, constraint set): three columns fit 80 columns however many sets there are
    table = Table(title=f"best valid run (utility J): {counted(surface.table.num_episodes, 'episode')}, "
                        f"{counted(surface.table.num_runs, 'run')}")
    table.add_column("objective", overflow="fold")
    table.add_column("constraint set", overflow="fold")
    table.add_column("best valid run (J)", overflow="fold")
    for cell in surface_cells(surface):
        if cell.objective in shown:
            table.add_row(cell.objective, cell.constraint_set,
                          f"{cell.best_run_id} ({cell.utility:.4g})" if cell.valid else "[red]none[/]")
    console.print(table)
    hidden = len(surface.objectives) - len(shown)
    if hidden:
        console.print(f"{counted(hidden, 'more objective')} (grid vectors, or past the first 12): see "
                      f"{files['markdown'].name} and the JSON", highlight=False)
    for name in document["constraint_sets_no_run_meets"]:
        console.print(f"[yellow]no run meets constraint set '{name}'[/]")
    front = document["pareto_front"]
    bound = ", ".join(f"{key} {value:.4g}" for key, value in front["reference_point"].items())
    runs = ", ".join(front["run_ids"])
    console.print(f"Pareto front: {counted(len(front['run_ids']), 'run')}: {runs}", highlight=False)
    console.print(f"hypervolume {front['hypervolume']:.6g} (reference point: {bound})", highlight=False)
    for kind, path in files.items():
        console.print(f"{kind}: {path}")


def episodes_from_files(paths: list[Path]) -> tuple[EpisodeTable, dict[str, Any]]:
    """The episodes of JSONL exports (one table), and where they came from."""
    tables = [read_episodes_jsonl(p) for p in paths]
    table = tables[0] if len(tables) == 1 else EpisodeTable.from_records(
        [rec for t in tables for rec in t.records()], ",".join(map(str, paths)))
    return table, {"episodes_jsonl": [str(p) for p in paths]}


def episodes_from_db(db_url: str, task_id: str | None, backend: str | None, datapacks: list[str],
                     objective: str | None, run_kind: str | None) -> tuple[EpisodeTable, dict[str, Any]]:
    """The recorded episodes of the runs the filters select, and the filters."""
    from econmotor.analysis.sources import episodes_from_registry

    with open_registry(db_url, create=False) as registry:
        note_abandoned(registry)
        table = episodes_from_registry(registry, task_id=task_id, backend=backend, datapacks=datapacks or None,
                                       objective=objective, kind=run_kind)
        source = {"registry": registry.display_url, "task_id": task_id, "backend": backend,
                  "datapacks": datapacks, "objective": objective, "run_kind": run_kind}
    return table, source
