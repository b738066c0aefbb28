"""``econmotor train`` and ``econmotor evaluate``: any motor backend, by factory name."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import typer
from rich.table import Table

from econmotor.cli._app import announce_device, app, console, progress_bars, set_cpu_threads
from econmotor.config.objective_profile import OBJECTIVE_PRESETS, ObjectiveVector
from econmotor.errors import ConfigError
from econmotor.motor_backend.datapacks import load_datapack_configs
from econmotor.motor_backend.factory import make_motor_backend
from econmotor.objectives import EconomicObjectiveSpec
from econmotor.objectives.loader import load_objective_spec, objective_from_vector
from econmotor.valuation import default_objective_vector

#: econ metrics shown after training / evaluation.
SHOWN_METRICS = ("mpl_units_per_hour", "error_rate", "energy_wh_per_unit", "implied_wage_usd_per_hour",
                 "wage_parity", "robot_unit_cost_usd", "human_unit_cost_usd", "spread_per_unit_usd")


# options shared by train and evaluate (module-level, as Typer allows and ruff's B008 prefers)
TASK_OPTION = typer.Option(..., "--task-id", "--task", help="Task id from the catalog (econmotor tasks).")
BACKEND_OPTION = typer.Option("mujoco", "--motor-backend", "--backend", help="Motor backend factory name.")
OBJECTIVE_CONFIG_OPTION = typer.Option(None, "--objective-config", help="Objective YAML.")
OBJECTIVE_PRESET_OPTION = typer.Option(None, "--objective-preset", help="Objective preset name.")
SEED_OPTION = typer.Option(0, "--seed")
JSON_OPTION = typer.Option(None, "--json", help="Also write the result as JSON here.")


def resolve_objective(config: Path | None, preset: str | None) -> EconomicObjectiveSpec:
    """The objective from a YAML file, a preset name, or RewardBuilder's default vector [1, 0.2, 0.1, 0.05, 0]."""
    if config is not None and preset is not None:
        raise ConfigError("<command line>", "--objective-preset", "give --objective-config or --objective-preset")
    if config is not None:
        return load_objective_spec(config)
    if preset is not None:
        if preset not in OBJECTIVE_PRESETS:
            raise ConfigError("<command line>", "--objective-preset", f"unknown preset '{preset}'", OBJECTIVE_PRESETS)
        return objective_from_vector(ObjectiveVector.from_preset(preset), name=preset)
    return objective_from_vector(ObjectiveVector.from_list(default_objective_vector()), name="default")


def render_result(title: str, raw: dict[str, Any], econ: dict[str, Any]) -> None:
    table = Table(title=title)
    table.add_column("metric")
    table.add_column("value", justify="right")
    for key in ("num_episodes", "return", "units_completed", "errors", "energy_wh"):
        if key in raw:
            table.add_row(key, f"{raw[key]:.4g}")
    for key in SHOWN_METRICS:
        if key in econ:
            table.add_row(key, f"{econ[key]:.4g}")
    console.print(table)


def write_json(path: Path | None, payload: dict[str, Any]) -> None:
    if path is not None:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps(payload, indent=2, default=str), encoding="utf-8")


@app.command("train")
def train_command(
    task: str = TASK_OPTION,
    backend: str = BACKEND_OPTION,
    objective_config: Path = OBJECTIVE_CONFIG_OPTION,
    objective_preset: str = OBJECTIVE_PRESET_OPTION,
    datapacks: list[Path] = typer.Option([], "--datapacks", help="Datapack YAML files (in order)."),
    num_envs: int = typer.Option(0, "--num-envs", help="Environments (0: the task's default)."),
    max_steps: int = typer.Option(100_000, "--max-steps", help="Total environment steps."),
    seed: int = SEED_OPTION,
    output_dir: Path = typer.Option(None, "--output-dir", help="Run directory (the policy id)."),
    eval_episodes: int = typer.Option(5, "--eval-episodes", help="Deterministic episodes after training."),
    resume: bool = typer.Option(False, "--resume", help="Continue the run in --output-dir from its last checkpoint."),
    algorithm: str = typer.Option(None, "--algorithm", help="Override the task's algorithm (mujoco: ppo | sac)."),
    vec_env: str = typer.Option(None, "--vec-env", help="mujoco: dummy (in-process, default) | subproc."),
    json_out: Path = JSON_OPTION,
) -> None:
    """Train a motor policy for an economic objective and print its economics."""
    set_cpu_threads()
    objective = resolve_objective(objective_config, objective_preset)
    configs = load_datapack_configs(datapacks)
    extra: dict[str, Any] = {}
    if resume:
        extra["resume"] = True
    if algorithm:
        extra["algorithm"] = algorithm
    if (extra and backend not in ("mujoco", "mjx")) or (vec_env and backend != "mujoco"):
        raise ConfigError("<command line>", "--resume/--algorithm/--vec-env",
                          f"backend '{backend}' does not support them", ["mujoco", "mjx (--resume, --algorithm)"])
    motor = make_motor_backend(backend, **({"vec_env": vec_env} if vec_env else {}))
    announce_device(motor)
    with progress_bars() as progress:
        result = motor.train_policy(task, objective, [c.id for c in configs],
                                    num_envs if (num_envs > 0 or backend in ("mujoco", "mjx")) else 1, max_steps, seed,
                                    datapack_configs=configs, output_dir=output_dir, eval_episodes=eval_episodes,
                                    progress=progress, **extra)
    render_result(f"{task} on {backend}: {result.policy_id}", result.raw_metrics, result.econ_metrics)
    if result.training_curve:
        last = result.training_curve[-1]
        console.print(f"training: {last['timesteps']:.0f} steps, mean return {last['mean_return']:.1f}")
    write_json(json_out, {"policy_id": result.policy_id, "raw_metrics": result.raw_metrics,
                          "econ_metrics": result.econ_metrics, "episodes": result.episodes,
                          "training_curve": result.training_curve, "artifacts": result.artifacts})


@app.command("evaluate")
def evaluate_command(
    policy: str = typer.Option(..., "--policy", help="Policy id (mujoco: the run directory)."),
    task: str = TASK_OPTION,
    backend: str = BACKEND_OPTION,
    objective_config: Path = OBJECTIVE_CONFIG_OPTION,
    objective_preset: str = OBJECTIVE_PRESET_OPTION,
    datapacks: list[Path] = typer.Option([], "--datapacks", help="Datapack YAML files applied while evaluating."),
    episodes: int = typer.Option(10, "--episodes", help="Deterministic evaluation episodes."),
    seed: int = SEED_OPTION,
    output_dir: Path = typer.Option(None, "--output-dir", help="Write evaluation.json here."),
    json_out: Path = JSON_OPTION,
) -> None:
    """Evaluate a trained policy deterministically and print its economics."""
    set_cpu_threads()
    objective = resolve_objective(objective_config, objective_preset)
    configs = load_datapack_configs(datapacks)
    motor = make_motor_backend(backend)
    announce_device(motor, "evaluating")
    with progress_bars() as progress:
        result = motor.evaluate_policy(policy, task, objective, episodes, seed, datapack_configs=configs,
                                       output_dir=output_dir, progress=progress)
    render_result(f"{task} on {backend}: {policy}", result.raw_metrics, result.econ_metrics)
    write_json(json_out, {"policy_id": result.policy_id, "raw_metrics": result.raw_metrics,
                          "econ_metrics": result.econ_metrics, "episodes": result.episodes})
