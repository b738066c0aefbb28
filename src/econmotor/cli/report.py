"""``econmotor report``: train (or reuse) a policy, price the task, write the reports.

Flags follow the spec's CLI (motor_backends.md): ``--task-id``, ``--motor-backend``,
``--objective-config``, ``--datapacks``, ``--objective-name``, ``--notes``,
``--num-envs``, ``--max-steps``, ``--eval-episodes``; plus ``--seed``, ``--output-dir``,
``--output-json``, ``--db-url`` (else ``ECONMOTOR_DB_URL``, else ./.econmotor/registry.sqlite),
``--tasks-file``, ``--spread-share`` and ``--run-id``. ``--datapacks`` takes YAML paths
or registered ids, comma separated, repeated, or space separated (values after the
flag that are not options are datapacks too).

Every input is validated before any training starts (and before anything is written):
:func:`econmotor.cli.reporting.run_report` does the work.
"""

from __future__ import annotations

from pathlib import Path

import typer

from econmotor.cli._app import app
from econmotor.cli.options import (
    EVAL_MAX_EPISODES_OPTION,
    EVAL_MAX_SECONDS_OPTION,
    INIT_POLICY_OPTION,
    SELECT_EPISODES_OPTION,
    SELECT_EVERY_OPTION,
    SPREAD_SHARE_OPTION,
    TASK_ID_OPTION,
    TASKS_FILE_OPTION,
    UNTIL_DEPLOYABLE_OPTION,
)
from econmotor.cli.reporting import NO_BACKEND, ReportArgs, run_report
from econmotor.motor_backend.factory import DEFAULT_BACKEND, known_backends
from econmotor.motor_backend.run_dir import REPORT_EVAL_SEED_OFFSET
from econmotor.store.engine import DB_URL_ENV

# the command's own flags (module-level, as Typer allows and ruff's B008 prefers)
MOTOR_BACKEND = typer.Option(DEFAULT_BACKEND, "--motor-backend",
                             help=f"{' | '.join(known_backends())} | {NO_BACKEND} (report from recorded runs).")
OBJECTIVE_CONFIG = typer.Option(None, "--objective-config", help="Objective YAML (3 forms).")
DATAPACKS = typer.Option([], "--datapacks", help="Datapack YAML paths or registered ids; comma separated, repeated, "
                         "or space separated.")
MORE_DATAPACKS = typer.Argument(None, help="More datapacks (space-separated --datapacks values).", show_default=False)
OBJECTIVE_NAME = typer.Option(None, "--objective-name", help="Name recorded for the objective.")
NOTES = typer.Option("", "--notes", help="Free text recorded with the runs and the report.")
NUM_ENVS = typer.Option(None, "--num-envs", min=0, help="Environments (default: the backend's).")
MAX_STEPS = typer.Option(None, "--max-steps", min=1, help="Training environment steps (default: the backend's).")
EVAL_EPISODES = typer.Option(None, "--eval-episodes", help="Price an evaluation run of exactly N fresh episodes "
                             "(default: a sequential evaluation: episodes in batches until the verdict is decided, "
                             "or a cap).")
SEED = typer.Option(0, "--seed", help=f"Seed of training (evaluation uses seed + {REPORT_EVAL_SEED_OFFSET}).")
OUTPUT_DIR = typer.Option(None, "--output-dir", help="Report directory (default reports/<task>).")
OUTPUT_JSON = typer.Option(None, "--output-json", help="Also choose where the JSON document goes.")
DB_URL = typer.Option(None, "--db-url", help=f"Registry URL (default ${DB_URL_ENV} or "
                      "sqlite:///./.econmotor/registry.sqlite).")
RUN_ID = typer.Option([], "--run-id", help="With --motor-backend none: a recorded run to price (repeatable; default: "
                      "the latest completed run of the task and objective).")
POLICY = typer.Option(None, "--policy", help="Price a policy trained elsewhere: an ONNX file or a shipped name "
                      "(holosoma:g1_29dof/ppo); nothing is trained, --eval-episodes N episodes are evaluated.")


@app.command("report", context_settings={"allow_interspersed_args": True})
def report_command(
    task_id: str = TASK_ID_OPTION,
    motor_backend: str = MOTOR_BACKEND,
    objective_config: Path = OBJECTIVE_CONFIG,
    datapacks: list[str] = DATAPACKS,
    more_datapacks: list[str] = MORE_DATAPACKS,
    objective_name: str = OBJECTIVE_NAME,
    notes: str = NOTES,
    num_envs: int = NUM_ENVS,
    max_steps: int = MAX_STEPS,
    eval_episodes: int = EVAL_EPISODES,
    eval_max_episodes: int = EVAL_MAX_EPISODES_OPTION,
    eval_max_seconds: float = EVAL_MAX_SECONDS_OPTION,
    seed: int = SEED,
    output_dir: Path = OUTPUT_DIR,
    output_json: Path = OUTPUT_JSON,
    db_url: str = DB_URL,
    tasks_file: list[Path] = TASKS_FILE_OPTION,
    spread_share: float = SPREAD_SHARE_OPTION,
    run_id: list[int] = RUN_ID,
    until_deployable: bool = UNTIL_DEPLOYABLE_OPTION,
    select_every: int = SELECT_EVERY_OPTION,
    select_episodes: int = SELECT_EPISODES_OPTION,
    imported_policy: str = POLICY,
    init_policy: str = INIT_POLICY_OPTION,
) -> None:
    """Train (or reuse) a policy for a task, price its labour, write JSON, Markdown and HTML reports."""
    run_report(ReportArgs(
        task_id=task_id, motor_backend=motor_backend, objective_config=objective_config,
        datapacks=(*datapacks, *(more_datapacks or [])), objective_name=objective_name, notes=notes,
        num_envs=num_envs, max_steps=max_steps, eval_episodes=eval_episodes, eval_max_episodes=eval_max_episodes,
        eval_max_seconds=eval_max_seconds, seed=seed, output_dir=output_dir, output_json=output_json, db_url=db_url,
        tasks_file=tuple(tasks_file), spread_share=spread_share, run_id=tuple(run_id),
        until_deployable=until_deployable, select_every=select_every, select_episodes=select_episodes,
        imported_policy=imported_policy, init_policy=init_policy))
