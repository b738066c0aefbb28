"""``econmotor report``: train (or reuse) a policy, price the task, write the reports.

Flags follow the spec's CLI (motor_backends.md): ``--task-id``, ``--motor-backend``,
``--objective-config``, ``--datapacks``, ``--objective-name``, ``--notes``,
``--num-envs``, ``--max-steps``, ``--eval-episodes``; plus ``--seed``, ``--output-dir``,
``--output-json``, ``--db-url`` (else ``ECONMOTOR_DB_URL``, else ./.econmotor/registry.sqlite),
``--tasks-file``, ``--spread-share`` and ``--run-id``. ``--datapacks`` takes YAML paths
or registered ids, comma separated, repeated, or space separated (values after the
flag that are not options are datapacks too).

Every input is validated before any training starts (and before anything is written).
"""

from __future__ import annotations

import os
import re
from pathlib import Path

import typer
from rich.table import Table

from econmotor.cli._app import (
    announce_device,
    announce_num_envs,
    app,
    console,
    err_console,
    make_backend,
    progress_bars,
    set_cpu_threads,
)
from econmotor.cli._interrupts import set_deadline_note
from econmotor.cli.train import (
    EVAL_MAX_EPISODES_OPTION,
    EVAL_MAX_SECONDS_OPTION,
    INIT_POLICY_OPTION,
    SELECT_EPISODES_OPTION,
    SELECT_EVERY_OPTION,
    TRAINING_EVAL_EPISODES,
    UNTIL_DEPLOYABLE_OPTION,
    init_policy_options,
    interrupted_note,
    selection_options,
)
from econmotor.cli.validation import (
    check_db_url,
    check_flags,
    check_input_files,
    check_name,
    check_num_envs,
    check_output_dir,
    check_output_file,
    check_task_backend,
    evaluation_plan,
    note_abandoned,
)
from econmotor.config.objective_profile import ObjectiveVector
from econmotor.economics.pricing import PricingPolicy
from econmotor.economics.uncertainty import SequentialPlan
from econmotor.errors import ConfigError, UnknownNameError, did_you_mean
from econmotor.motor_backend.base import REPORT_EVAL_SEED_OFFSET
from econmotor.motor_backend.datapacks import DatapackConfig, load_datapack_configs
from econmotor.motor_backend.factory import DEFAULT_BACKEND, backend_class, known_backends, load_checked_catalog
from econmotor.objectives import load_objective_spec, objective_from_vector
from econmotor.objectives.economic_objective import EconomicObjectiveSpec
from econmotor.report.pipeline import (
    ReportOutcome,
    TrainRequest,
    evaluate_and_record,
    pick_runs,
    report_after_training,
    report_from_registry,
    train_and_record,
    with_objective_name,
)
from econmotor.report.render import (
    INTERVAL_COLUMN,
    headline,
    imported_policy_text,
    selection_text,
    started_from_text,
    table_rows,
)
from econmotor.store.registry import DB_URL_ENV, Registry, registry_exists
from econmotor.valuation import default_objective_vector

NO_BACKEND = "none"


def split_datapack_values(values: list[str]) -> list[str]:
    """``["a.yaml,b", "c d"]`` -> ``["a.yaml", "b", "c", "d"]`` (commas and spaces separate)."""
    return [tok for value in values for tok in re.split(r"[,\s]+", value) if tok]


def _looks_like_path(token: str) -> bool:
    return token.endswith((".yaml", ".yml")) or "/" in token or os.sep in token or Path(token).exists()


def resolve_datapacks(tokens: list[str], db_url: str) -> list[DatapackConfig]:
    """YAML paths are loaded; other tokens are ids registered in the registry (read only)."""
    configs: list[DatapackConfig] = []
    ids = [t for t in tokens if not _looks_like_path(t)]
    registered: dict[str, DatapackConfig] = {}
    known: list[str] = []
    if ids and registry_exists(db_url):
        with Registry(db_url, create=False) as reg:
            known = reg.known_datapack_ids()
            registered = {c.id: c for c in reg.datapack_configs([i for i in ids if i in known])}
    for token in tokens:
        if _looks_like_path(token):
            configs.extend(load_datapack_configs([token]))  # a missing file is a ConfigError
        elif token in registered:
            configs.append(registered[token])
        else:
            raise ConfigError("--datapacks", token, "unknown datapack id and not a YAML file; a datapack is "
                              "registered when a report first uses its YAML path" + did_you_mean(token, known),
                              sorted(known) or "a YAML path (no datapack ids registered yet)")
    seen: set[str] = set()
    return [c for c in configs if not (c.id in seen or seen.add(c.id))]


def resolve_objective(path: Path | None, name: str | None) -> EconomicObjectiveSpec:
    """The objective file, or the RewardBuilder default vector [1, 0.2, 0.1, 0.05, 0] named 'default'."""
    if path is not None:
        check_input_files("--objective-config", [path])
    objective = load_objective_spec(path) if path is not None else \
        objective_from_vector(ObjectiveVector.from_list(default_objective_vector()), "default")
    return with_objective_name(objective, name)


def describe_pick(train, priced, task_id: str, asked: list[int], objective: str | None) -> str:
    """Which run is priced and why, in words."""
    what = f"{priced.kind} run of objective '{priced.objective_name}'"
    if train is not None and train.id != priced.id:
        what += f", evaluating the policy of training run #{train.id}"
    if priced.notes == "econmotor sweep" or (train is not None and train.notes == "econmotor sweep"):
        what += " (a sweep cell)"
    finished = priced.finished_at.strftime("%Y-%m-%d %H:%M UTC") if priced.finished_at else "unknown time"
    if asked:
        why = "asked for with --run-id" if priced.id in asked else f"the newest completed evaluation of run " \
              f"#{train.id if train else '?'} (asked for with --run-id)"
    else:
        why = (f"the latest completed run of task '{task_id}'"
               + (f" and objective '{objective}'" if objective else " (any objective; choose with --objective-name)")
               + "; pass --run-id N to price another")
    return f"{what}, finished {finished}: {why}"


def show_outcome(outcome: ReportOutcome) -> None:
    """The verdict and headline first, then the table (estimate and 90% interval) and where the files are."""
    doc = outcome.document
    verdict = doc["verdict"]
    console.print(f"[bold {'green' if verdict['deployable'] else 'red'}]{verdict['label'].upper()}[/]",
                  highlight=False)
    console.print(headline(doc), highlight=False)
    if doc.get("selection"):
        console.print(f"policy kept: {selection_text(doc['selection'])}", highlight=False)
    if doc.get("started_from"):
        console.print(f"started from: {started_from_text(doc['started_from'])}", highlight=False)
    title = "diagnostics (not a price)" if not verdict["deployable"] else "pricing"
    table = Table(title=f"{doc['task']['task_id']} on {doc['backend']}: objective {doc['objective']['name']}, "
                        f"spread share {doc['pricing']['spread_share']:g}; {title}")
    table.add_column("metric (unit)", ratio=1, overflow="fold")
    table.add_column("estimate", justify="right", no_wrap=True)
    table.add_column(INTERVAL_COLUMN, justify="right", no_wrap=True)
    for label, estimate, interval, *_, unit in table_rows(doc):
        table.add_row(f"{label} ({unit})", estimate, interval)
    console.print(table)
    for kind, path in outcome.files.items():
        console.print(f"{kind:>8}: {path}", highlight=False, soft_wrap=True)
    console.print(f"HTML report: {outcome.files['html']}", style="bold green", highlight=False, soft_wrap=True)


def check_imports_policies(backend_name: str, flag: str) -> None:
    """``backend_name`` must evaluate policies trained elsewhere (its ``capabilities.imported_policies``)."""
    if not backend_class(backend_name).capabilities.imported_policies:
        raise ConfigError(flag, backend_name, "this backend evaluates its own run directories only, not imported "
                          "policies", [n for n in known_backends() if backend_class(n).capabilities.imported_policies])


def price_imported(task, backend, policy_id: str, objective: EconomicObjectiveSpec, packs: list[DatapackConfig],
                   eval_episodes: int, seed: int, notes: str, url: str, out_dir: Path, output_json: Path | None,
                   pricing: PricingPolicy, plan: SequentialPlan | None = None) -> ReportOutcome:
    """Evaluate an imported policy (nothing trained; ``eval_episodes``, or sequentially under ``plan``), record
    the evaluation run, write its report."""
    request = TrainRequest(task=task, backend_name=backend.name, objective=objective, datapacks=tuple(packs),
                           seed=seed, eval_episodes=0 if plan is not None else eval_episodes, eval_plan=plan,
                           notes=notes,
                           output_dir=backend.run_dir(None, task.task_id, seed))
    with progress_bars() as progress:
        reg, eval_id = evaluate_and_record(request, backend, policy_id, lambda: Registry(url), progress)
    with reg:
        return report_from_registry(reg, task, reg.run(eval_id), None, out_dir, output_json, pricing)


def report_imported(task, backend, policy_id: str, objective: EconomicObjectiveSpec,
                    packs: list[DatapackConfig], eval_episodes: int | None, plan: SequentialPlan | None, seed: int,
                    notes: str, url: str, out_dir: Path, output_json: Path | None, pricing: PricingPolicy) -> None:
    """``report --policy``: evaluate an imported policy (nothing trained), record the run, write the report."""
    backend.check_policy(policy_id)  # bad input records nothing
    outcome = price_imported(task, backend, policy_id, objective, packs, eval_episodes or 0, seed, notes, url,
                             out_dir, output_json, pricing, plan)
    console.print(f"[bold]evaluated[/]: {imported_policy_text(outcome.document['runs']['eval'])}", highlight=False)
    show_outcome(outcome)


@app.command("report", context_settings={"allow_interspersed_args": True})
def report_command(
    task_id: str = typer.Option(..., "--task-id", help="Task id from the catalog (`econmotor tasks`)."),
    motor_backend: str = typer.Option(DEFAULT_BACKEND, "--motor-backend",
                                      help=f"{' | '.join(known_backends())} | {NO_BACKEND} (report from recorded "
                                      "runs)."),
    objective_config: Path = typer.Option(None, "--objective-config", help="Objective YAML (3 forms)."),
    datapacks: list[str] = typer.Option([], "--datapacks", help="Datapack YAML paths or registered ids; "
                                        "comma separated, repeated, or space separated."),
    more_datapacks: list[str] = typer.Argument(None, help="More datapacks (space-separated --datapacks values).",
                                               show_default=False),
    objective_name: str = typer.Option(None, "--objective-name", help="Name recorded for the objective."),
    notes: str = typer.Option("", "--notes", help="Free text recorded with the runs and the report."),
    num_envs: int = typer.Option(None, "--num-envs", min=0, help="Environments (default: the backend's)."),
    max_steps: int = typer.Option(None, "--max-steps", min=1, help="Training environment steps "
                                  "(default: the backend's)."),
    eval_episodes: int = typer.Option(None, "--eval-episodes",
                                      help="Price an evaluation run of exactly N fresh episodes (default: a "
                                      "sequential evaluation: episodes in batches until the verdict is decided, "
                                      "or a cap)."),
    eval_max_episodes: int = EVAL_MAX_EPISODES_OPTION,
    eval_max_seconds: float = EVAL_MAX_SECONDS_OPTION,
    seed: int = typer.Option(0, "--seed", help=f"Seed of training (evaluation uses seed + {REPORT_EVAL_SEED_OFFSET})."),
    output_dir: Path = typer.Option(None, "--output-dir", help="Report directory (default reports/<task>)."),
    output_json: Path = typer.Option(None, "--output-json", help="Also choose where the JSON document goes."),
    db_url: str = typer.Option(None, "--db-url", help=f"Registry URL (default ${DB_URL_ENV} or "
                               "sqlite:///./.econmotor/registry.sqlite)."),
    tasks_file: list[Path] = typer.Option([], "--tasks-file", help="Extra task catalog YAML files."),
    spread_share: float = typer.Option(0.5, "--spread-share", help="Seller's share of the spread, 0..1."),
    run_id: list[int] = typer.Option([], "--run-id", help="With --motor-backend none: a recorded run to price "
                                     "(repeatable; default: the latest completed run of the task and objective)."),
    until_deployable: bool = UNTIL_DEPLOYABLE_OPTION,
    select_every: int = SELECT_EVERY_OPTION,
    select_episodes: int = SELECT_EPISODES_OPTION,
    imported_policy: str = typer.Option(None, "--policy", help="Price a policy trained elsewhere: an ONNX file "
                                        "or a shipped name (holosoma:g1_29dof/ppo); nothing is trained, "
                                        "--eval-episodes N episodes are evaluated."),
    init_policy: str = INIT_POLICY_OPTION,
) -> None:
    """Train (or reuse) a policy for a task, price its labour, write JSON, Markdown and HTML reports."""
    set_cpu_threads()
    # ---- validate everything first: nothing is trained or written on bad input
    check_flags(num_envs=num_envs, max_steps=max_steps, eval_episodes=eval_episodes, seed=seed,
                spread_share=spread_share, run_id=run_id, eval_max_episodes=eval_max_episodes,
                eval_max_seconds=eval_max_seconds)
    check_name("--objective-name", objective_name)
    check_output_file("--output-json", output_json)
    policy = PricingPolicy(spread_share)
    url = check_db_url(db_url, create=motor_backend != NO_BACKEND)
    catalog = load_checked_catalog(tasks_file)
    task = catalog.get(task_id)
    backends = [*known_backends(), NO_BACKEND]
    if motor_backend not in backends:
        raise UnknownNameError("motor backend", motor_backend, backends)
    if motor_backend != NO_BACKEND:
        check_task_backend(task, motor_backend)
        check_num_envs(motor_backend, num_envs)
    if run_id and motor_backend != NO_BACKEND:
        raise ConfigError("--run-id", None, "--run-id reports a recorded run: use it with --motor-backend none")
    selecting = selection_options(motor_backend, until_deployable, select_every, select_episodes) \
        if motor_backend != NO_BACKEND else {}
    if init_policy is not None and (imported_policy is not None or motor_backend == NO_BACKEND):
        raise ConfigError("--init-policy", init_policy, "starts a training run from a policy; --policy and "
                          "--motor-backend none price without training")
    if motor_backend != NO_BACKEND:
        selecting.update(init_policy_options(motor_backend, init_policy))
    objective = resolve_objective(objective_config, objective_name)
    packs = resolve_datapacks(split_datapack_values([*datapacks, *(more_datapacks or [])]), url)
    out_dir = check_output_dir("--output-dir", output_dir or Path("reports") / task_id)

    if motor_backend == NO_BACKEND:
        ignored = [flag for flag, value in (("--num-envs", num_envs), ("--max-steps", max_steps),
                                             ("--eval-episodes", eval_episodes),
                                             ("--eval-max-episodes", eval_max_episodes),
                                             ("--eval-max-seconds", eval_max_seconds),
                                             ("--objective-config", objective_config),
                                             ("--until-deployable", until_deployable or None),
                                             ("--select-every", select_every),
                                             ("--select-episodes", select_episodes)) if value is not None]
        if ignored:
            err_console.print(f"[yellow]note[/]: {', '.join(ignored)} ignored: --motor-backend none prices a "
                              "recorded run without training or evaluating")
        if not registry_exists(url):
            raise ConfigError("--db-url", None, f"no registry at {url}; train a run first")
        wanted_objective = objective_name or (objective.name if objective_config is not None else None)
        with Registry(url, create=False) as reg:
            note_abandoned(reg)
            chosen = [pick_runs(reg, task_id, rid) for rid in run_id] if run_id else \
                [pick_runs(reg, task_id, None, wanted_objective, [p.id for p in packs] or None)]
            once = {priced.id: (train, priced) for train, priced in chosen}  # a run and its evaluation: once
            if len(once) < len(chosen):
                err_console.print(f"[yellow]note[/]: the --run-id values name {len(once)} distinct run(s) to "
                                  "price (a training run is priced by its evaluation run); each is priced once",
                                  highlight=False)
            chosen = list(once.values())
            for train, priced in chosen:
                why = describe_pick(train, priced, task_id, run_id, wanted_objective)
                console.print(f"[bold]pricing run #{priced.id}[/]: {why}", highlight=False)
                if len(chosen) > 1 and output_json is not None:
                    raise ConfigError("--output-json", None, "one JSON path cannot hold several reports: drop "
                                      "--output-json (each run's JSON goes to --output-dir) or give one --run-id")
                show_outcome(report_from_registry(reg, task, priced, train, out_dir, output_json, policy,
                                                  notes or None))
        return

    if imported_policy is not None:
        check_imports_policies(motor_backend, "--motor-backend")
    size = backend_class(motor_backend).defaults.filled(num_envs, max_steps)
    backend = make_backend(motor_backend, tasks_file, catalog=catalog)
    plan = evaluation_plan(backend, task_id, eval_episodes, eval_max_episodes, eval_max_seconds)
    if imported_policy is not None:
        report_imported(task, backend, imported_policy, objective, packs, eval_episodes, plan, seed, notes,
                        url, out_dir, output_json, policy)
        return
    if init_policy is not None:
        backend.check_init_policy(init_policy, task_id)
    run_dir = backend.run_dir(None, task_id, seed)
    announce_device(backend)
    announce_num_envs(backend, task_id, num_envs)
    request = TrainRequest(task=task, backend_name=motor_backend, objective=objective, datapacks=tuple(packs),
                           num_envs=size.num_envs, max_steps=size.max_steps, seed=seed,
                           eval_episodes=eval_episodes or 0, eval_plan=plan, notes=notes, output_dir=run_dir,
                           backend_options=selecting,
                           # an evaluation run follows and is priced: the one after training stays small
                           train_eval_episodes=TRAINING_EVAL_EPISODES)

    def note() -> str:
        return (f"{interrupted_note(motor_backend, task_id, run_dir, request.max_steps, 'report')}. "
                f"Registry: {url}; runs completed before are kept (price one with: econmotor report "
                f"--motor-backend none --task-id {task_id} --run-id N)")

    set_deadline_note(note)
    try:
        with progress_bars() as progress:
            reg, train_id, eval_id = train_and_record(request, backend, lambda: Registry(url), progress)
    except KeyboardInterrupt:
        err_console.print(f"[yellow]interrupted[/]: {note()}", highlight=False)
        raise typer.Abort from None
    with reg:
        show_outcome(report_after_training(reg, request, train_id, eval_id, out_dir, output_json, policy))
