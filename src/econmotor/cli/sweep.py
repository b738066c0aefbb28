"""``econmotor sweep``: train objective x datapacks x seeds, or evaluate a policy at each commanded speed x
datapacks x seeds (``--policy``, ``--command-speed``), and record every cell in the registry."""

from __future__ import annotations

import os
from pathlib import Path

import typer
from rich.table import Table

from econmotor.analysis.eval_sweep import plan_eval_sweep
from econmotor.analysis.objective_surface import objectives_from_options
from econmotor.analysis.sweep import RaySettings, completed_cell_keys, plan_sweep, run_sweep
from econmotor.cli._app import app, console, err_console, make_backend, progress_bars, set_cpu_threads
from econmotor.cli._interrupts import set_deadline_note
from econmotor.cli.options import check_imports_policies, course_speed_options, open_registry, split_ids
from econmotor.cli.validation import (
    MAX_SWEEP_CELLS,
    check_command_speeds,
    check_db_url,
    check_flags,
    check_output_dir,
    check_size,
    check_task_backend,
    note_abandoned,
    parse_seed_list,
    simplex_size,
)
from econmotor.config.datapacks import DatapackConfig, load_datapack_configs
from econmotor.couriers.policy_import import is_imported_policy
from econmotor.errors import ConfigError
from econmotor.motor_backend.base import MotorBackendBase
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


TASK = typer.Option(..., "--task-id", help="Task id from the catalog (econmotor tasks).")
BACKEND = typer.Option("dishwashing", "--motor-backend", help="Backend that trains (or evaluates) each cell.")
PRESETS = typer.Option([], "--preset", help="Objective presets (comma list or repeated).")
VECTORS = typer.Option([], "--vector", help="Objective vector 'mpl,error,energy,safety,novelty'.")
GRID = typer.Option(0, "--grid", help="Add every simplex weight vector with step 1/GRID.")
DATAPACKS = typer.Option([], "--datapacks", help="Grid values: YAML paths or registered ids, comma separated; "
                         "'a.yaml+b.yaml' is one value using both.")
SEEDS = typer.Option("0", "--seeds", help="Seeds, e.g. '0,1,2' or '0-4'.")
POLICY = typer.Option(None, "--policy", help="Evaluate this policy instead of training: a shipped name "
                      "(holosoma:g1_29dof/ppo), an ONNX file or a run directory; one evaluation run per "
                      "--command-speed x --datapacks x --seeds.")
COMMAND_SPEEDS = typer.Option(None, "--command-speed", help="Commanded walking speeds, m/s, e.g. '0.4,0.6,0.8,1.0' "
                              "(with --policy, on a backend whose evaluation walks a course at a commanded speed); "
                              "default: the task catalog's.")
NUM_ENVS = typer.Option(None, "--num-envs", min=0, help="Environments per cell (default: the backend's).")
MAX_STEPS = typer.Option(None, "--max-steps", min=1, help="Environment steps per cell (default: the backend's).")
EVAL_EPISODES = typer.Option(5, "--eval-episodes", help="Evaluation episodes recorded per cell.")
OUTPUT_DIR = typer.Option(Path("runs/sweep"), "--output-dir", help="Policies land in OUTPUT_DIR/<cell key>.")
DB_URL = typer.Option(None, "--db-url", help="Registry URL (default $ECONMOTOR_DB_URL or "
                      "./.econmotor/registry.sqlite).")
USE_RAY = typer.Option(False, "--ray", help="Run each cell as a Ray task (local Ray unless --ray-address).")
RAY_ADDRESS = typer.Option(None, "--ray-address", help="Ray cluster address (implies --ray).")
RAY_NUM_CPUS = typer.Option(None, "--ray-num-cpus", help="CPUs of a local Ray.")
CPUS_PER_CELL = typer.Option(None, "--cpus-per-cell", help="CPUs each Ray task declares (default: what the backend "
                             "says a cell needs).")
GPUS_PER_CELL = typer.Option(None, "--gpus-per-cell", help="GPUs each Ray task declares (default: the backend's: "
                             "one where it trains on a GPU that is present).")


@app.command("sweep")
def sweep_command(
    task_id: str = TASK, motor_backend: str = BACKEND, preset: list[str] = PRESETS, vector: list[str] = VECTORS,
    grid: int = GRID, datapacks: list[str] = DATAPACKS, seeds: str = SEEDS, policy: str = POLICY,
    command_speed: str = COMMAND_SPEEDS, num_envs: int = NUM_ENVS, max_steps: int = MAX_STEPS,
    eval_episodes: int = EVAL_EPISODES, output_dir: Path = OUTPUT_DIR, db_url: str = DB_URL, use_ray: bool = USE_RAY,
    ray_address: str = RAY_ADDRESS, ray_num_cpus: int = RAY_NUM_CPUS, cpus_per_cell: float = CPUS_PER_CELL,
    gpus_per_cell: float = GPUS_PER_CELL,
) -> None:
    """Train a grid of objective x datapacks x seeds, or (--policy) evaluate a policy at each --command-speed x
    datapacks x seeds; completed cells are skipped on re-runs."""
    check_flags(grid=grid, num_envs=num_envs, max_steps=max_steps, eval_episodes=eval_episodes,
                ray_num_cpus=ray_num_cpus, cpus_per_cell=cpus_per_cell, gpus_per_cell=gpus_per_cell)
    seed_list = parse_seeds(seeds)
    check_output_dir("--output-dir", output_dir)
    url = check_db_url(db_url)
    check_task_backend(load_catalog().get(task_id), motor_backend)
    cls = backend_class(motor_backend)  # resolved once; the checks below ask it
    speeds = parse_command_speeds(command_speed, cls, policy)
    if policy is None:
        check_size("--grid", "objectives (sweep cells before seeds and datapacks)", simplex_size(grid),
                   MAX_SWEEP_CELLS)
        cls.check_num_envs(num_envs, "--num-envs")
        grid_axis: list = objectives_from_options(preset, vector, grid)
    else:
        check_evaluation_flags(cls, policy, preset, vector, grid, num_envs, max_steps, eval_episodes)
        grid_axis = speeds
    check_size("--seeds", "sweep cells (objectives or speeds x seeds)", len(grid_axis) * len(seed_list),
               MAX_SWEEP_CELLS)
    set_cpu_threads()
    kept = (f"each in {output_dir}/<cell key>/ and in the registry. Resume by running the same command again: "
            "completed cells are skipped.")
    set_deadline_note(lambda: f"Completed cells are kept, {kept}")
    with open_registry(url) as registry:
        note_abandoned(registry)
        groups = datapack_groups(datapacks, registry)
        check_size("--datapacks", "sweep cells (objectives or speeds x datapacks x seeds)",
                   len(grid_axis) * len(groups) * len(seed_list), MAX_SWEEP_CELLS)
        size = cls.defaults.filled(num_envs, max_steps)
        cells = plan_sweep(task_id, motor_backend, grid_axis, groups, seed_list, num_envs=size.num_envs,
                           max_steps=size.max_steps, eval_episodes=eval_episodes) if policy is None else \
            plan_eval_sweep(task_id, motor_backend, policy, grid_axis, groups, seed_list, eval_episodes=eval_episodes)
        ray = ray_settings(cls, use_ray, ray_address, ray_num_cpus, cpus_per_cell, gpus_per_cell)
        console.print(f"sweep: {len(cells)} {'evaluation ' if policy else ''}cells on {motor_backend} "
                      f"({'Ray' if ray else 'sequential'}); registry {registry.display_url}")
        outcomes = run_cells(registry, cells, output_dir, ray, kept)
    if policy is None:
        print_cells(outcomes)
    else:
        print_eval_cells(outcomes, policy)
    console.print(f"then: econmotor solve --task-id {task_id} --motor-backend {motor_backend}"
                  + (" --run-kind eval" if policy else "") + (f" --db-url {db_url}" if db_url else ""))
    if any(o.status == "failed" for o in outcomes):
        raise typer.Exit(1)


def parse_command_speeds(text: str | None, backend: type[MotorBackendBase], policy: str | None) -> list[float | None]:
    """``"0.4,0.6,0.8,1.0"`` -> speeds in m/s, each a valid ``--command-speed`` (``[None]`` when not given: the
    task catalog's); refused without ``--policy`` and for a backend that walks no course at a commanded speed."""
    if text is None:
        return [None]
    try:
        speeds = [float(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise ConfigError("--command-speed", text, "expected comma-separated speeds in m/s",
                          "e.g. 0.4,0.6,0.8,1.0") from None
    if not speeds:
        raise ConfigError("--command-speed", text, "no speed given", "e.g. 0.4,0.6,0.8,1.0")
    check_command_speeds(speeds, [policy] if policy else [])
    if len(set(speeds)) != len(speeds):
        raise ConfigError("--command-speed", text, "a speed is named twice")
    if policy is None:
        raise ConfigError("--command-speed", text, "sweeps the operating point of a policy that exists: give "
                          "--policy (training one policy per commanded speed is not supported yet)",
                          "a shipped name (holosoma:g1_29dof/ppo), an ONNX file or a run directory, with --policy")
    course_speed_options(backend, speeds[0])  # the backend must walk a course at a commanded speed
    return list(speeds)


def check_evaluation_flags(backend: type[MotorBackendBase], policy: str, preset: list[str], vector: list[str],
                           grid: int, num_envs: int | None, max_steps: int | None, eval_episodes: int) -> None:
    """An evaluation sweep (``--policy``) trains nothing and has no objective axis; its policy must exist and be
    one the backend evaluates (a file or shipped name only on a backend that imports policies)."""
    given = [flag for flag, value in (("--preset", preset), ("--vector", vector), ("--grid", grid),
                                      ("--num-envs", num_envs is not None), ("--max-steps", max_steps is not None))
             if value]
    if given:
        raise ConfigError(given[0], None, "--policy evaluates a policy that exists (one run per speed, datapacks "
                          "and seed; `econmotor solve` scores its episodes under every objective): leave "
                          f"{', '.join(given)} out", "--command-speed, --datapacks, --seeds, --eval-episodes")
    if eval_episodes < 1:
        raise ConfigError("--eval-episodes", None, "an evaluation sweep needs episodes: give N >= 1")
    if is_imported_policy(policy):
        check_imports_policies(backend, "--motor-backend")
    elif not Path(policy).is_dir():
        raise ConfigError("--policy", policy, "no such run directory",
                          "a shipped name (holosoma:<robot>/<algo>), an ONNX file or a run directory")
    make_backend(backend.name).check_policy(policy)


def ray_settings(backend: type[MotorBackendBase], use_ray: bool, address: str | None, num_cpus: int | None,
                 cpus_per_cell: float | None, gpus_per_cell: float | None) -> RaySettings | None:
    """Ray's settings of a sweep (None: cells run one after another here); a cell declares what the
    backend says it needs unless the flags say otherwise."""
    if not (use_ray or address):
        return None
    needs = backend.sweep_resources()
    return RaySettings(address, num_cpus, needs["num_cpus"] if cpus_per_cell is None else cpus_per_cell,
                       needs["num_gpus"] if gpus_per_cell is None else gpus_per_cell)


def run_cells(registry, cells: list, output_dir: Path, ray: RaySettings | None, kept: str) -> list:
    """Run the cells with progress bars; interrupted: say what is kept and abort."""
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


def _figure(econ: dict | None, key: str, spec: str) -> str:
    value = (econ or {}).get(key)
    return "-" if value is None else format(value, spec)


def print_eval_cells(outcomes: list, policy: str) -> None:
    """One row per evaluation cell: speed, datapacks, seed, status, run, units/h, Wh/unit, errors, cell key."""
    table = Table(title=f"sweep cells: {policy}")
    for col in ("speed m/s", "datapacks", "seed", "status", "run", "units/h", "Wh/unit", "errors", "cell key"):
        table.add_column(col, overflow="fold")
    for o in outcomes:
        status = {"failed": f"[red]failed: {o.error}[/]", "skipped": "skipped (done before)"}.get(o.status, o.status)
        speed = o.cell.command_speed_m_per_s
        econ = o.econ_metrics
        table.add_row("catalog" if speed is None else f"{speed:g}", "+".join(o.cell.datapack_ids) or "-",
                      str(o.cell.seed), status, str(o.run_id or "-"), _figure(econ, "mpl_units_per_hour", ".4g"),
                      _figure(econ, "energy_wh_per_unit", ".4g"), _figure(econ, "errors", "g"), o.cell.key)
    console.print(table)
