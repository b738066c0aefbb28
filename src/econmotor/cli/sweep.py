"""``econmotor sweep``: train objective x datapacks x seeds and record every cell in the registry."""

from __future__ import annotations

import os
from pathlib import Path

import typer
from rich.table import Table

from econmotor.analysis.objective_surface import objectives_from_options
from econmotor.analysis.sweep import RaySettings, completed_cell_keys, plan_sweep, run_sweep
from econmotor.cli._app import app, console, err_console, progress_bars, set_cpu_threads
from econmotor.cli._interrupts import set_deadline_note
from econmotor.cli.options import open_registry, split_ids
from econmotor.cli.validation import (
    MAX_SWEEP_CELLS,
    check_db_url,
    check_flags,
    check_num_envs,
    check_output_dir,
    check_size,
    check_task_backend,
    note_abandoned,
    parse_seed_list,
    simplex_size,
)
from econmotor.motor_backend.datapacks import DatapackConfig, load_datapack_configs
from econmotor.motor_backend.factory import backend_class, environment_options
from econmotor.tasks import load_catalog


def datapack_groups(values: list[str], registry) -> list[list[DatapackConfig]]:
    """Each comma-separated entry is one grid value; ``a.yaml+b`` trains with both packs.

    An entry is a datapack YAML path or an id registered in the registry.
    """
    groups = []
    for entry in split_ids(values):
        group = []
        for item in entry.split("+"):
            path = Path(item)
            if path.suffix in (".yaml", ".yml") or path.exists():
                group += load_datapack_configs([path])
            else:
                group += registry.datapack_configs([item])
        groups.append(group)
    return groups or [[]]


def parse_seeds(text: str) -> list[int]:
    """``"0,1,2"`` or ``"0-4"`` -> seeds (each a valid --seed; at most MAX_SWEEP_SEEDS)."""
    return parse_seed_list(text)


@app.command("sweep")
def sweep_command(
    task_id: str = typer.Option(..., "--task-id", help="Task id from the catalog (econmotor tasks)."),
    motor_backend: str = typer.Option("dishwashing", "--motor-backend", help="Backend that trains each cell."),
    preset: list[str] = typer.Option([], "--preset", help="Objective presets (comma list or repeated)."),
    vector: list[str] = typer.Option([], "--vector", help="Objective vector 'mpl,error,energy,safety,novelty'."),
    grid: int = typer.Option(0, "--grid", help="Add every simplex weight vector with step 1/GRID."),
    datapacks: list[str] = typer.Option([], "--datapacks", help="Grid values: YAML paths or registered ids, "
                                        "comma separated; 'a.yaml+b.yaml' is one value using both."),
    seeds: str = typer.Option("0", "--seeds", help="Seeds, e.g. '0,1,2' or '0-4'."),
    num_envs: int = typer.Option(None, "--num-envs", min=0, help="Environments per cell (default: the "
                                 "backend's)."),
    max_steps: int = typer.Option(None, "--max-steps", min=1, help="Environment steps per cell (default: the "
                                  "backend's)."),
    eval_episodes: int = typer.Option(5, "--eval-episodes", help="Evaluation episodes recorded per cell."),
    output_dir: Path = typer.Option(Path("runs/sweep"), "--output-dir", help="Policies land in OUTPUT_DIR/<cell key>."),
    db_url: str = typer.Option(None, "--db-url", help="Registry URL (default $ECONMOTOR_DB_URL or "
                               "./.econmotor/registry.sqlite)."),
    use_ray: bool = typer.Option(False, "--ray", help="Run each cell as a Ray task (local Ray unless --ray-address)."),
    ray_address: str = typer.Option(None, "--ray-address", help="Ray cluster address (implies --ray)."),
    ray_num_cpus: int = typer.Option(None, "--ray-num-cpus", help="CPUs of a local Ray."),
    cpus_per_cell: float = typer.Option(None, "--cpus-per-cell", help="CPUs each Ray task declares (default: "
                                        "what the backend says a cell needs)."),
    gpus_per_cell: float = typer.Option(None, "--gpus-per-cell", help="GPUs each Ray task declares (default: "
                                        "the backend's: one where it trains on a GPU that is present)."),
) -> None:
    """Train a grid of objective x datapacks x seeds; completed cells are skipped on re-runs."""
    check_flags(grid=grid, num_envs=num_envs, max_steps=max_steps, eval_episodes=eval_episodes,
                ray_num_cpus=ray_num_cpus, cpus_per_cell=cpus_per_cell, gpus_per_cell=gpus_per_cell)
    seed_list = parse_seeds(seeds)
    check_size("--grid", "objectives (sweep cells before seeds and datapacks)", simplex_size(grid), MAX_SWEEP_CELLS)
    check_output_dir("--output-dir", output_dir)
    url = check_db_url(db_url)
    check_task_backend(load_catalog().get(task_id), motor_backend)
    check_num_envs(motor_backend, num_envs)
    objectives = objectives_from_options(preset, vector, grid)
    check_size("--seeds", "sweep cells (objectives x seeds)", len(objectives) * len(seed_list), MAX_SWEEP_CELLS)
    set_cpu_threads()
    kept = (f"each in {output_dir}/<cell key>/ and in the registry. Resume by running the same command again: "
            "completed cells are skipped.")
    set_deadline_note(lambda: f"Completed cells are kept, {kept}")
    with open_registry(url) as registry:
        note_abandoned(registry)
        groups = datapack_groups(datapacks, registry)
        check_size("--datapacks", "sweep cells (objectives x datapacks x seeds)",
                   len(objectives) * len(groups) * len(seed_list), MAX_SWEEP_CELLS)
        size = backend_class(motor_backend).defaults.filled(num_envs, max_steps)
        cells = plan_sweep(task_id, motor_backend, objectives, groups, seed_list, num_envs=size.num_envs,
                           max_steps=size.max_steps, eval_episodes=eval_episodes)
        ray = ray_settings(motor_backend, use_ray, ray_address, ray_num_cpus, cpus_per_cell, gpus_per_cell)
        console.print(f"sweep: {len(cells)} cells on {motor_backend} "
                      f"({'Ray' if ray else 'sequential'}); registry {registry.display_url}")
        outcomes = run_cells(registry, cells, output_dir, ray, kept)
    print_cells(outcomes)
    failed = sum(o.status == "failed" for o in outcomes)
    console.print(f"then: econmotor solve --task-id {task_id} --motor-backend {motor_backend}"
                  + (f" --db-url {db_url}" if db_url else ""))
    if failed:
        raise typer.Exit(1)


def ray_settings(backend: str, use_ray: bool, address: str | None, num_cpus: int | None,
                 cpus_per_cell: float | None, gpus_per_cell: float | None) -> RaySettings | None:
    """Ray's settings of a sweep (None: cells run one after another here); a cell declares what the
    backend says it needs unless the flags say otherwise."""
    if not (use_ray or address):
        return None
    needs = backend_class(backend).sweep_resources()
    return RaySettings(address, num_cpus, needs["num_cpus"] if cpus_per_cell is None else cpus_per_cell,
                       needs["num_gpus"] if gpus_per_cell is None else gpus_per_cell)


def run_cells(registry, cells: list, output_dir: Path, ray: RaySettings | None, kept: str) -> list:
    """Train the cells with progress bars; interrupted: say what is kept and abort."""
    backend = cells[0].backend
    try:
        with progress_bars() as progress:
            return run_sweep(registry, cells, output_dir, ray=ray, progress=progress,
                             backend_options=environment_options(backend, os.environ))
    except KeyboardInterrupt:
        done = completed_cell_keys(registry, cells[0].task_id, backend) & {c.key for c in cells}
        err_console.print(f"[yellow]interrupted[/]: the cells in flight are recorded as interrupted in "
                          f"{registry.display_url}. Kept: {len(done)} of {len(cells)} cells completed, {kept}",
                          highlight=False)
        raise typer.Abort from None


def print_cells(outcomes: list) -> None:
    """One row per cell: objective, datapacks, seed, status, run, mean J, cell key."""
    table = Table(title="sweep cells")
    for col in ("objective", "datapacks", "seed", "status", "run", "mean J", "cell key"):
        table.add_column(col, overflow="fold")  # wrap, never cut: ids and keys are copied by users
    for o in outcomes:
        status = {"failed": f"[red]failed: {o.error}[/]", "skipped": "skipped (done before)"}.get(o.status, o.status)
        table.add_row(o.cell.objective.name, "+".join(o.cell.datapack_ids) or "-", str(o.cell.seed), status,
                      str(o.run_id or "-"), "-" if o.mean_j is None else f"{o.mean_j:.4g}", o.cell.key)
    console.print(table)
