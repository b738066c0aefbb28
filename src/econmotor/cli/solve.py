"""``econmotor solve``: the objective surface over recorded episodes.

Reads episodes from the registry (filters: task, backend, datapacks, objective) or
from JSONL exports, scores every run under every objective and constraint set, and
writes ``objective_surface.json``, ``objective_surface.md`` and ``pareto_front.png``.
Each named objective's choice comes with its mean J and its margin over the runner-up
(90% intervals); where the runs walk a commanded speed (``econmotor sweep --policy ...
--command-speed``), the table shows each candidate's speed and a second table each run's
operating point (units/h, Wh/unit, units per charge, errors, price, with intervals).
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import typer
from rich.table import Table

from econmotor.analysis.episode_table import EpisodeTable, read_episodes_jsonl, write_episodes_jsonl
from econmotor.analysis.objective_surface import objectives_from_options, solve_objective_surface
from econmotor.analysis.operating_point import choices, operating_points, task_economics
from econmotor.analysis.surface_report import interval_text, surface_cells, write_surface_outputs
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
    speeds = any(run.commanded_speed_m_per_s is not None for run in table.runs)
    points = operating_points(table, task_economics(sorted({r.task_id for r in table.runs}))) if speeds else []
    files = write_surface_outputs(surface, output_dir, reference,
                                  {**source, "constraints": str(constraints) if constraints else None},
                                  choices(surface), points)
    _print_summary(surface, files)


def _choice_table(surface, document: dict[str, Any], shown: list[str]) -> Table:
    """One row per (objective, constraint set): the best valid run, its speed (where runs have one), its J and
    its margin over the runner-up, with 90% intervals."""
    speeds = {r["run_id"]: r["commanded_speed_m_per_s"] for r in document["runs"]}
    with_speed = any(v is not None for v in speeds.values())
    chosen = {(c["objective"], c["constraint_set"]): c for c in document["choices"]}
    table = Table(title=f"best valid run (utility J, 90% intervals): "
                        f"{counted(surface.table.num_episodes, 'episode')}, {counted(surface.table.num_runs, 'run')}")
    columns = ["objective", "constraint set", "best valid run", *(["speed m/s"] if with_speed else []), "J",
               "margin over runner-up"]
    for col in columns:
        table.add_column(col, overflow="fold")
    for cell in surface_cells(surface):
        if cell.objective not in shown:
            continue
        if not cell.valid:
            table.add_row(cell.objective, cell.constraint_set, "[red]none[/]", *([""] if with_speed else []), "", "")
            continue
        c = chosen[(cell.objective, cell.constraint_set)]
        margin = "-" if c["margin"] is None else \
            f"{interval_text(c['margin'])} vs {c['runner_up_run_id']}" + ("" if c["separated"] else " (not separated)")
        speed = speeds[cell.best_run_id]
        table.add_row(cell.objective, cell.constraint_set, cell.best_run_id,
                      *([f"{speed:g}" if speed is not None else "-"] if with_speed else []),
                      interval_text(c["utility"], ".4g"), margin)
    return table


def _operating_table(points: list[dict[str, Any]]) -> Table:
    """Each run's operating point (pooled, 90% intervals), in speed order."""
    table = Table(title="operating points (pooled over each run's episodes, 90% intervals)")
    for col in ("speed m/s", "run", "episodes", "units/h", "Wh/unit", "units/charge", "errors (bound)",
                "price USD/unit", "damage USD/unit"):
        table.add_column(col, overflow="fold")
    for p in sorted(points, key=lambda p: (p["commanded_speed_m_per_s"] is None, p["commanded_speed_m_per_s"] or 0)):
        f, ev = p["figures"], p["evidence"]
        speed = p["commanded_speed_m_per_s"]
        table.add_row("-" if speed is None else f"{speed:g}", p["run_id"], str(ev["episodes"]),
                      interval_text(f["mpl_units_per_hour"]), interval_text(f["energy_wh_per_unit"]),
                      interval_text(f.get("battery_units_per_charge")),
                      f"{ev['errors']:g} in {ev['units_attempted']:.3g} ({f['error_rate']['high']:.3g})",
                      interval_text(f["price_usd_per_unit"]), interval_text(f["damage_usd_per_unit"]))
    return table


def _print_summary(surface, files) -> None:
    """The choice table (grid objectives only in the files), the operating points where the runs walk a
    commanded speed, the unmet sets, the Pareto front and the files."""
    import json

    document = json.loads(files["json"].read_text())
    shown = [o.name for o in surface.objectives if o.kind != "grid"][:12]
    console.print(_choice_table(surface, document, shown))
    if document["operating_points"]:
        console.print(_operating_table(document["operating_points"]))
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
