"""``econmotor train`` and ``econmotor evaluate``: any motor backend, by factory name."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import typer
from rich.table import Table

from econmotor.cli._app import (
    announce_device,
    announce_num_envs,
    app,
    console,
    make_backend,
    progress_bars,
    set_cpu_threads,
)
from econmotor.cli.options import (
    HYPERPARAMETERS_OPTION,
    INIT_POLICY_OPTION,
    SELECT_EPISODES_OPTION,
    SELECT_EVERY_OPTION,
    TRAINING_EVAL_EPISODES,
    UNTIL_DEPLOYABLE_OPTION,
    hyperparameter_options,
    init_policy_options,
    resolve_objective,
    selection_options,
    time_budget_options,
    training_eval_episodes,
)
from econmotor.cli.runs import interrupted_note, train_with_bars
from econmotor.cli.validation import (
    check_choice,
    check_db_url,
    check_flags,
    check_output_dir,
    check_output_file,
    check_task_backend,
)
from econmotor.config.datapacks import load_datapack_configs
from econmotor.errors import ConfigError
from econmotor.motor_backend.base import MotorBackendBase
from econmotor.motor_backend.factory import DEFAULT_BACKEND, backend_class, known_backends
from econmotor.motor_backend.selection import evaluation_cost_text
from econmotor.recording import TrainRequest
from econmotor.store.registry import Registry
from econmotor.tasks import load_catalog

#: econ metrics shown after training / evaluation.
SHOWN_METRICS = ("mpl_units_per_hour", "error_rate", "energy_wh_per_unit", "implied_wage_usd_per_hour",
                 "wage_parity", "robot_unit_cost_usd", "human_unit_cost_usd", "spread_per_unit_usd")


# options shared by train and evaluate (module-level, as Typer allows and ruff's B008 prefers)
TASK_OPTION = typer.Option(..., "--task-id", "--task", help="Task id from the catalog (econmotor tasks).")
BACKEND_OPTION = typer.Option(DEFAULT_BACKEND, "--motor-backend", "--backend",
                              help=f"Motor backend: {' | '.join(known_backends())}.")
OBJECTIVE_CONFIG_OPTION = typer.Option(None, "--objective-config", help="Objective YAML.")
OBJECTIVE_PRESET_OPTION = typer.Option(None, "--objective-preset", help="Objective preset name.")
SEED_OPTION = typer.Option(0, "--seed")
JSON_OPTION = typer.Option(None, "--json", help="Also write the result as JSON here.")
# train's own
DATAPACKS_OPTION = typer.Option([], "--datapacks", help="Datapack YAML files (in order).")
NUM_ENVS_OPTION = typer.Option(None, "--num-envs", min=0, help="Environments (default: the backend's; 0: the task's).")
MAX_STEPS_OPTION = typer.Option(None, "--max-steps", min=1, help="Total environment steps (default: the backend's).")
OUTPUT_DIR_OPTION = typer.Option(None, "--output-dir", help="Run directory (the policy id; default: a new "
                                 "runs/<task>-<time>-s<seed>-<pid>).")
EVAL_EPISODES_OPTION = typer.Option(None, "--eval-episodes", help="Deterministic episodes after training (default "
                                    f"{TRAINING_EVAL_EPISODES}; with --until-deployable as many as a held-out "
                                    "evaluation, enough for a verdict).")
RESUME_OPTION = typer.Option(False, "--resume", help="Continue the interrupted run in --output-dir from its last "
                             "checkpoint (a complete run is left as it is).")
ALGORITHM_OPTION = typer.Option(None, "--algorithm", help="Override the task's algorithm (the backend's "
                                "capabilities list the choices).")
VEC_ENV_OPTION = typer.Option(None, "--vec-env", help="Vector env kind, for backends that offer a choice "
                              "(e.g. dummy: in-process | subproc).")
DB_URL_OPTION = typer.Option(None, "--db-url", help="Registry URL (default $ECONMOTOR_DB_URL or "
                             "sqlite:///./.econmotor/registry.sqlite).")


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


def completed_run_note(backend: str, run_dir: Path) -> str | None:
    """What a finished run of ``backend`` holds, or ``None`` when ``run_dir`` has no final policy."""
    from econmotor.motor_backend.run_dir import read_run_config

    cls = backend_class(backend)
    if not cls.is_complete_run(run_dir):
        return None
    final = cls.final_policy_file
    config = read_run_config(run_dir)
    return (f"{run_dir} is a complete run ({config.get('algorithm', '?')}, trained with --max-steps "
            f"{config.get('max_steps', '?'):,}, final {final})" if isinstance(config.get("max_steps"), int)
            else f"{run_dir} is a complete run (final {final})")


def selection_note(run_config: dict[str, Any]) -> str | None:
    """Which checkpoint a run kept and why, when it became deployable and what its evaluations cost."""
    selection = run_config.get("selection")
    if not selection:
        return None
    cost = selection["evaluation_cost"]
    first = selection.get("became_deployable")
    when = (f"deployable on held-out episodes after {first['env_steps']:,} env steps ({first['wall_s']:.0f} s); "
            if first else "")
    spent = (f"{evaluation_cost_text(cost)} ({cost['episodes']} episodes)."
             if cost["count"] else "")
    return f"policy kept: {selection['why']}. {when}{spent}".rstrip()


def check_backend_choices(backend: type[MotorBackendBase], algorithm: str | None, vec_env: str | None,
                          resume: bool) -> None:
    """``--algorithm``, ``--vec-env`` and ``--resume`` against what the backend (its class) declares it offers."""
    capabilities = backend.capabilities
    for flag, value, allowed in (("--algorithm", algorithm, capabilities.algorithms),
                                 ("--vec-env", vec_env, capabilities.vec_env_kinds)):
        if value is not None and not allowed:
            raise ConfigError("<command line>", flag, f"backend '{backend.name}' offers no choice here: leave it out")
        check_choice(flag, value, allowed)
    if resume and not capabilities.resume:
        raise ConfigError("<command line>", "--resume", f"backend '{backend.name}' cannot resume a run",
                          [b for b in known_backends() if backend_class(b).capabilities.resume])


def nothing_to_resume(backend: str, output_dir: Path | None) -> bool:
    """``--resume``: True (and says so) when ``output_dir`` already holds a complete run; an error without one."""
    if output_dir is None:
        raise ConfigError("<command line>", "--resume", "needs --output-dir: the run directory to continue")
    complete = completed_run_note(backend, output_dir)
    if complete is not None:
        console.print(f"{complete}: nothing to resume, nothing changed. To train further, start a new run "
                      "(a new --output-dir, or none for a fresh directory).", highlight=False)
    return complete is not None


def show_trained(registry: Registry, run_id: int, task: str, backend: str, json_out: Path | None) -> None:
    """A recorded training run's economics, the checkpoint it kept, where it is and how to price it."""
    with registry:
        record = registry.run(run_id)
    render_result(f"{task} on {backend}: run #{run_id}", record.raw_metrics, record.econ_metrics)
    if record.training_curve:
        last = record.training_curve[-1]
        console.print(f"training: {last['timesteps']:.0f} steps, mean return {last['mean_return']:.1f}")
    note = selection_note((record.config or {}).get("backend_config") or {})
    if note:
        console.print(note, highlight=False)
    console.print(f"recorded as run #{run_id} in {registry.display_url}; run directory {record.policy_path}; "
                  f"price it with: econmotor report --motor-backend none --task-id {task} --run-id {run_id}",
                  highlight=False)
    write_json(json_out, {"run_id": run_id, "policy_id": record.policy_path, "raw_metrics": record.raw_metrics,
                          "econ_metrics": record.econ_metrics,
                          "episodes": [e.summary for e in registry.episodes(run_ids=[run_id])],
                          "training_curve": record.training_curve, "artifacts": record.artifacts})


@app.command("train")
def train_command(
    task: str = TASK_OPTION,
    backend: str = BACKEND_OPTION,
    objective_config: Path = OBJECTIVE_CONFIG_OPTION,
    objective_preset: str = OBJECTIVE_PRESET_OPTION,
    datapacks: list[Path] = DATAPACKS_OPTION,
    num_envs: int = NUM_ENVS_OPTION,
    max_steps: int = MAX_STEPS_OPTION,
    seed: int = SEED_OPTION,
    output_dir: Path = OUTPUT_DIR_OPTION,
    eval_episodes: int = EVAL_EPISODES_OPTION,
    resume: bool = RESUME_OPTION,
    algorithm: str = ALGORITHM_OPTION,
    vec_env: str = VEC_ENV_OPTION,
    until_deployable: bool = UNTIL_DEPLOYABLE_OPTION,
    select_every: int = SELECT_EVERY_OPTION,
    select_episodes: int = SELECT_EPISODES_OPTION,
    init_policy: str = INIT_POLICY_OPTION,
    hyperparameters: list[str] = HYPERPARAMETERS_OPTION,
    max_minutes: float = typer.Option(None, "--max-minutes", help="Stop training after this many minutes of wall "
                                      "time (held-out selection included; backends with a time budget)."),
    db_url: str = DB_URL_OPTION,
    json_out: Path = JSON_OPTION,
) -> None:
    """Train a motor policy for an economic objective, record it in the registry, print its economics."""
    eval_episodes = training_eval_episodes(eval_episodes, until_deployable, select_episodes)
    check_flags(num_envs=num_envs, max_steps=max_steps, seed=seed, eval_episodes=eval_episodes)
    cls = backend_class(backend)  # resolved once; the checks below ask it
    cls.check_num_envs(num_envs, "--num-envs")
    check_backend_choices(cls, algorithm, vec_env, resume)
    check_output_dir("--output-dir", output_dir)
    check_output_file("--json", json_out)
    objective = resolve_objective(objective_config, objective_preset)
    configs = load_datapack_configs(datapacks)
    spec = load_catalog().get(task)
    check_task_backend(spec, backend)
    set_cpu_threads()
    extra: dict[str, Any] = {**selection_options(cls, until_deployable, select_every, select_episodes),
                             **init_policy_options(cls, init_policy, resume),
                             **({"resume": True} if resume else {}), **({"algorithm": algorithm} if algorithm else {}),
                             **time_budget_options(cls, max_minutes),
                             **hyperparameter_options(cls, hyperparameters, resume)}
    if resume and nothing_to_resume(backend, output_dir):
        return
    motor = make_backend(backend, **({"vec_env": vec_env} if vec_env else {}))
    if init_policy is not None:
        motor.check_init_policy(init_policy, task)
    announce_device(motor)
    announce_num_envs(motor, task, num_envs)
    url = check_db_url(db_url)
    run_dir = motor.run_dir(output_dir, task, seed)
    size = motor.defaults.filled(num_envs, max_steps)
    request = TrainRequest(task=spec, backend_name=backend, objective=objective, datapacks=tuple(configs),
                           num_envs=size.num_envs, max_steps=size.max_steps, seed=seed,
                           train_eval_episodes=eval_episodes, output_dir=run_dir, backend_options=extra)
    registry, run_id, _ = train_with_bars(
        request, motor, url,
        lambda: f"{interrupted_note(backend, task, run_dir, size.max_steps, init_policy=init_policy)} (registry {url})")
    show_trained(registry, run_id, task, backend, json_out)


@app.command("evaluate")
def evaluate_command(
    policy: str = typer.Option(..., "--policy", help="Policy id: a run directory (or, for a backend that "
                               "imports policies, a policy file or shipped name)."),
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
    check_flags(episodes=episodes, seed=seed)
    check_output_dir("--output-dir", output_dir)
    check_output_file("--json", json_out)
    objective = resolve_objective(objective_config, objective_preset)
    configs = load_datapack_configs(datapacks)
    set_cpu_threads()
    motor = make_backend(backend)
    announce_device(motor, "evaluating")
    with progress_bars() as progress:
        result = motor.evaluate_policy(policy, task, objective, episodes, seed, datapack_configs=configs,
                                       output_dir=output_dir, progress=progress)
    render_result(f"{task} on {backend}: {policy}", result.raw_metrics, result.econ_metrics)
    write_json(json_out, {"policy_id": result.policy_id, "raw_metrics": result.raw_metrics,
                          "econ_metrics": result.econ_metrics, "episodes": result.episodes})
