"""The task pricing report from the command line (``report``, ``demo``, ``compare``), in three ways:

- from recorded runs (``--motor-backend none``): price a run of the registry again;
- an imported policy (``--policy``): evaluate a policy trained elsewhere, record the run, price it;
- training: train a policy, evaluate it on fresh episodes, record both, price the evaluation.

:class:`ReportArgs` holds the ``report`` flags as given; :func:`run_report` validates every input before
anything is trained or written, runs the way asked and prints the verdict, the table and where the
files are. Registers no command: ``cli/report.py`` and ``cli/demo.py`` call :func:`run_report`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from rich.table import Table

from econmotor.cli._app import (
    announce_device,
    announce_num_envs,
    console,
    err_console,
    make_backend,
    progress_bars,
    set_cpu_threads,
)
from econmotor.cli.options import (
    TRAINING_EVAL_EPISODES,
    check_imports_policies,
    init_policy_options,
    resolve_datapacks,
    resolve_objective,
    selection_options,
    split_datapack_values,
)
from econmotor.cli.runs import interrupted_note, train_with_bars
from econmotor.cli.validation import (
    check_db_url,
    check_flags,
    check_name,
    check_output_dir,
    check_output_file,
    check_task_backend,
    evaluation_plan,
    note_abandoned,
)
from econmotor.config.datapacks import DatapackConfig
from econmotor.economics.pricing import PricingPolicy
from econmotor.economics.sequential_rule import SequentialPlan
from econmotor.errors import ConfigError, UnknownNameError
from econmotor.motor_backend.factory import DEFAULT_BACKEND, backend_class, known_backends, load_checked_catalog
from econmotor.objectives.economic_objective import EconomicObjectiveSpec
from econmotor.recording import TrainRequest, evaluate_and_record
from econmotor.report.pipeline import ReportOutcome, pick_runs, report_after_training, report_from_registry
from econmotor.report.text import (
    INTERVAL_COLUMN,
    headline,
    imported_policy_text,
    selection_text,
    started_from_text,
    table_rows,
)
from econmotor.store.engine import registry_exists
from econmotor.store.registry import Registry

#: ``--motor-backend none``: price recorded runs, train nothing
NO_BACKEND = "none"


@dataclass(frozen=True)
class ReportArgs:
    """The flags of ``econmotor report`` as given (None: not given); the defaults are the flags' defaults.

    ``datapacks`` holds ``--datapacks`` values and the space-separated ones after them, unsplit."""

    task_id: str
    motor_backend: str = DEFAULT_BACKEND
    objective_config: Path | None = None
    datapacks: tuple[str, ...] = ()
    objective_name: str | None = None
    notes: str = ""
    num_envs: int | None = None
    max_steps: int | None = None
    eval_episodes: int | None = None
    eval_max_episodes: int | None = None
    eval_max_seconds: float | None = None
    seed: int = 0
    output_dir: Path | None = None
    output_json: Path | None = None
    db_url: str | None = None
    tasks_file: tuple[Path, ...] = ()
    spread_share: float = 0.5
    run_id: tuple[int, ...] = ()
    until_deployable: bool = False
    select_every: int | None = None
    select_episodes: int | None = None
    imported_policy: str | None = None
    init_policy: str | None = None
    #: the learner's hyperparameters over the catalog's (``train --hyperparameters``; the demo's own)
    hyperparameters: dict[str, Any] | None = None

    @property
    def trains(self) -> bool:
        """A backend runs (not ``--motor-backend none``)."""
        return self.motor_backend != NO_BACKEND


@dataclass(frozen=True)
class ReportInputs:
    """What every way of reporting uses, checked: the task (and its catalog), registry URL, objective,
    datapacks, report directory, pricing policy and the backend options of training."""

    task: Any
    catalog: Any
    url: str
    objective: EconomicObjectiveSpec
    packs: list[DatapackConfig]
    out_dir: Path
    pricing: PricingPolicy
    backend_options: dict[str, Any] = field(default_factory=dict)
    backend_cls: Any = None  # the backend's class, resolved once (None: --motor-backend none)


def run_report(a: ReportArgs) -> None:
    """Validate every input, then report from recorded runs, an imported policy, or a training run."""
    inputs = check_report_args(a)
    if not a.trains:
        report_recorded(a, inputs)
        return
    set_cpu_threads()
    if a.imported_policy is not None:
        check_imports_policies(inputs.backend_cls, "--motor-backend")
    backend = make_backend(a.motor_backend, a.tasks_file, catalog=inputs.catalog)
    plan = evaluation_plan(backend, a.task_id, a.eval_episodes, a.eval_max_episodes, a.eval_max_seconds)
    if a.imported_policy is not None:
        report_imported(inputs, backend, a.imported_policy, a.eval_episodes, plan, a.seed, a.notes, a.output_json)
    else:
        report_trained(a, inputs, backend, plan)


def check_report_args(a: ReportArgs) -> ReportInputs:
    """Every flag of ``report`` checked before anything is trained or written; the inputs they name."""
    check_flags(num_envs=a.num_envs, max_steps=a.max_steps, eval_episodes=a.eval_episodes, seed=a.seed,
                spread_share=a.spread_share, run_id=list(a.run_id), eval_max_episodes=a.eval_max_episodes,
                eval_max_seconds=a.eval_max_seconds)
    check_name("--objective-name", a.objective_name)
    check_output_file("--output-json", a.output_json)
    pricing = PricingPolicy(a.spread_share)
    url = check_db_url(a.db_url, create=a.trains)
    catalog = load_checked_catalog(a.tasks_file)
    task = catalog.get(a.task_id)
    backends = [*known_backends(), NO_BACKEND]
    if a.motor_backend not in backends:
        raise UnknownNameError("motor backend", a.motor_backend, backends)
    cls = backend_class(a.motor_backend) if a.trains else None  # resolved once; every check below asks it
    if cls is not None:
        check_task_backend(task, a.motor_backend)
        cls.check_num_envs(a.num_envs, "--num-envs")
    if a.run_id and a.trains:
        raise ConfigError("--run-id", None, "--run-id reports a recorded run: use it with --motor-backend none")
    options = selection_options(cls, a.until_deployable, a.select_every, a.select_episodes) if cls else {}
    if a.init_policy is not None and (a.imported_policy is not None or not a.trains):
        raise ConfigError("--init-policy", a.init_policy, "starts a training run from a policy; --policy and "
                          "--motor-backend none price without training")
    if cls is not None:
        options.update(init_policy_options(cls, a.init_policy))
        if a.hyperparameters:
            options["hyperparameters"] = dict(a.hyperparameters)
    objective = resolve_objective(a.objective_config, name=a.objective_name)
    packs = resolve_datapacks(split_datapack_values(list(a.datapacks)), url)
    out_dir = check_output_dir("--output-dir", a.output_dir or Path("reports") / a.task_id)
    return ReportInputs(task, catalog, url, objective, packs, out_dir, pricing, options, cls)


def _ignored_by_recorded(a: ReportArgs) -> list[str]:
    """The flags ``--motor-backend none`` ignores that were given."""
    return [flag for flag, value in (("--num-envs", a.num_envs), ("--max-steps", a.max_steps),
                                     ("--eval-episodes", a.eval_episodes),
                                     ("--eval-max-episodes", a.eval_max_episodes),
                                     ("--eval-max-seconds", a.eval_max_seconds),
                                     ("--objective-config", a.objective_config),
                                     ("--until-deployable", a.until_deployable or None),
                                     ("--select-every", a.select_every),
                                     ("--select-episodes", a.select_episodes)) if value is not None]


def report_recorded(a: ReportArgs, inputs: ReportInputs) -> None:
    """``--motor-backend none``: price recorded runs (``--run-id``, else the latest matching one)."""
    ignored = _ignored_by_recorded(a)
    if ignored:
        err_console.print(f"[yellow]note[/]: {', '.join(ignored)} ignored: --motor-backend none prices a "
                          "recorded run without training or evaluating")
    if not registry_exists(inputs.url):
        raise ConfigError("--db-url", None, f"no registry at {inputs.url}; train a run first")
    wanted_objective = a.objective_name or (inputs.objective.name if a.objective_config is not None else None)
    with Registry(inputs.url, create=False) as reg:
        note_abandoned(reg)
        chosen = [pick_runs(reg, a.task_id, rid) for rid in a.run_id] if a.run_id else \
            [pick_runs(reg, a.task_id, None, wanted_objective, [p.id for p in inputs.packs] or None)]
        once = {priced.id: (train, priced) for train, priced in chosen}  # a run and its evaluation: once
        if len(once) < len(chosen):
            err_console.print(f"[yellow]note[/]: the --run-id values name {len(once)} distinct run(s) to "
                              "price (a training run is priced by its evaluation run); each is priced once",
                              highlight=False)
        chosen = list(once.values())
        for train, priced in chosen:
            why = describe_pick(train, priced, a.task_id, list(a.run_id), wanted_objective)
            console.print(f"[bold]pricing run #{priced.id}[/]: {why}", highlight=False)
            if len(chosen) > 1 and a.output_json is not None:
                raise ConfigError("--output-json", None, "one JSON path cannot hold several reports: drop "
                                  "--output-json (each run's JSON goes to --output-dir) or give one --run-id")
            show_outcome(report_from_registry(reg, inputs.task, priced, train, inputs.out_dir, a.output_json,
                                              inputs.pricing, a.notes or None))


def report_trained(a: ReportArgs, inputs: ReportInputs, backend: Any, plan: SequentialPlan | None) -> None:
    """Train a policy, evaluate it on fresh episodes (``--eval-episodes N``, or sequentially under ``plan``),
    record both runs and price the evaluation."""
    if a.init_policy is not None:
        backend.check_init_policy(a.init_policy, a.task_id)
    size = backend.defaults.filled(a.num_envs, a.max_steps)
    run_dir = backend.run_dir(None, a.task_id, a.seed)
    announce_device(backend)
    announce_num_envs(backend, a.task_id, a.num_envs)
    request = TrainRequest(task=inputs.task, backend_name=a.motor_backend, objective=inputs.objective,
                           datapacks=tuple(inputs.packs), num_envs=size.num_envs, max_steps=size.max_steps,
                           seed=a.seed, eval_episodes=a.eval_episodes or 0, eval_plan=plan, notes=a.notes,
                           output_dir=run_dir, backend_options=inputs.backend_options,
                           # an evaluation run follows and is priced: the one after training stays small
                           train_eval_episodes=TRAINING_EVAL_EPISODES)

    def note() -> str:
        return (f"{interrupted_note(a.motor_backend, a.task_id, run_dir, request.max_steps, 'report', a.init_policy)}. "
                f"Registry: {inputs.url}; runs completed before are kept (price one with: econmotor report "
                f"--motor-backend none --task-id {a.task_id} --run-id N)")

    reg, train_id, eval_id = train_with_bars(request, backend, inputs.url, note)
    with reg:
        show_outcome(report_after_training(reg, request, train_id, eval_id, inputs.out_dir, a.output_json,
                                           inputs.pricing))


def price_imported(inputs: ReportInputs, backend: Any, policy_id: str, eval_episodes: int, seed: int, notes: str,
                   output_json: Path | None, plan: SequentialPlan | None = None) -> ReportOutcome:
    """Evaluate an imported policy (nothing trained; ``eval_episodes``, or sequentially under ``plan``), record
    the evaluation run, write its report."""
    task = inputs.task
    request = TrainRequest(task=task, backend_name=backend.name, objective=inputs.objective,
                           datapacks=tuple(inputs.packs), seed=seed, eval_episodes=0 if plan is not None else
                           eval_episodes, eval_plan=plan, notes=notes,
                           output_dir=backend.run_dir(None, task.task_id, seed))
    with progress_bars() as progress:
        reg, eval_id = evaluate_and_record(request, backend, policy_id, lambda: Registry(inputs.url), progress)
    with reg:
        return report_from_registry(reg, task, reg.run(eval_id), None, inputs.out_dir, output_json, inputs.pricing)


def report_imported(inputs: ReportInputs, backend: Any, policy_id: str, eval_episodes: int | None,
                    plan: SequentialPlan | None, seed: int, notes: str, output_json: Path | None) -> None:
    """``report --policy``: evaluate an imported policy (nothing trained), record the run, write the report."""
    backend.check_policy(policy_id)  # bad input records nothing
    outcome = price_imported(inputs, backend, policy_id, eval_episodes or 0, seed, notes, output_json, plan)
    console.print(f"[bold]evaluated[/]: {imported_policy_text(outcome.document['runs']['eval'])}", highlight=False)
    show_outcome(outcome)


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
