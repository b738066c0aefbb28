"""The task pricing report from recorded runs: pick the runs -> price -> render.

:func:`report_from_registry` builds and writes the report from recorded runs only; the runs come from
:mod:`econmotor.recording` (train and evaluate through a backend, each run recorded). The CLI
(``econmotor report``) validates the inputs, records what it trains, then reports. Nothing here prints.
If the report fails after training, the trained run stays in the registry and the error says how to
report from it (``econmotor report --motor-backend none --run-id N``).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from econmotor.config.loading import path_name
from econmotor.economics.pricing import PricingPolicy, price_evaluation
from econmotor.errors import BackendError, RegistryError
from econmotor.objectives.economic_objective import EconomicObjectiveSpec
from econmotor.recording import TrainRequest, how_to_report_from
from econmotor.report.document import ReportContext, build_document
from econmotor.report.render import report_paths, write_report
from econmotor.store.records import RunRecord
from econmotor.store.registry import Registry


@dataclass(frozen=True)
class ReportOutcome:
    """What a report produced: the document, its files and the registry ids involved."""

    document: dict[str, Any]
    files: dict[str, str]
    report_id: int
    train_run: RunRecord | None
    eval_run: RunRecord | None


def pick_runs(registry: Registry, task_id: str, run_id: int | None = None, objective: str | None = None,
              datapacks: list[str] | None = None, backend: str | None = None) -> tuple[RunRecord | None, RunRecord]:
    """(training run, run to price) for a report from recorded runs.

    With ``run_id``: that run (a training run is priced by its newest completed evaluation
    run if it has one). Without: the newest completed run of the task matching the filters.
    """
    if run_id is not None:
        chosen = registry.run(run_id)
        if chosen.task_id != task_id:
            raise RegistryError(f"run #{run_id} is a run of task '{chosen.task_id}', not '{task_id}'")
        if chosen.status != "completed":
            raise RegistryError(f"run #{run_id} is {chosen.status} ({chosen.error or 'no error recorded'}); "
                                "only completed runs can be priced")
    else:
        priceable = [r for r in registry.runs(task_id=task_id, status="completed", objective=objective,
                                              datapacks=datapacks, backend=backend) if r.kind in ("train", "eval")]
        chosen = priceable[-1] if priceable else None
        if chosen is None:
            raise RegistryError(
                f"no completed run of task '{task_id}' in the registry {registry.display_url}"
                + (" matching the given objective/datapacks" if objective or datapacks else "")
                + f"; train one first (econmotor train --task-id {task_id}; econmotor tasks --show {task_id} "
                  "lists the backends that run it)")
    if chosen.kind not in ("train", "eval"):
        raise RegistryError(f"run #{chosen.id} is a {chosen.kind} run: it has no evaluation episodes to price")
    if chosen.kind == "eval":
        train = registry.run(chosen.parent_run_id) if chosen.parent_run_id is not None else None
        return train, chosen
    evals = [r for r in registry.child_runs(chosen.id) if r.status == "completed"]
    return chosen, (evals[-1] if evals else chosen)


def report_from_registry(registry: Registry, task: Any, priced: RunRecord, train: RunRecord | None,
                         output_dir: str | Path, json_path: str | Path | None = None,
                         policy: PricingPolicy | None = None, notes: str | None = None) -> ReportOutcome:
    """Price the episodes of ``priced`` with ``task``'s economics, record and write the report."""
    episodes = [e.summary for e in registry.episodes(run_ids=[priced.id], status=None)]
    if not episodes or not priced.econ_metrics:
        raise RegistryError(f"run #{priced.id} has no evaluation episodes to price; evaluate its policy "
                            "with --eval-episodes N, or pick another run with --run-id")
    pricing = price_evaluation(task.economics, priced.econ_metrics, episodes, policy or PricingPolicy())
    objective = EconomicObjectiveSpec(**{k: v for k, v in priced.objective.items()
                                         if k in EconomicObjectiveSpec.__dataclass_fields__}) \
        if priced.objective else EconomicObjectiveSpec()
    ctx = ReportContext(
        task=task, backend=priced.backend, objective=objective, datapack_ids=priced.datapack_ids,
        pricing=pricing, raw_metrics=priced.raw_metrics, econ_metrics=priced.econ_metrics, episodes=episodes,
        train_run=train, eval_run=priced if priced.kind == "eval" else None,
        training_curve=(train or priced).training_curve,
        notes=notes if notes is not None else (train or priced).notes, db_url=registry.display_url)
    document = build_document(ctx)
    name = path_name(f"{task.task_id}_run{priced.id}", "<report>", "name")
    written: dict[str, Any] = {}

    def write_files(report_id: int) -> dict[str, str]:  # inside the registry transaction: no row without files
        written["document"] = {**document, "registry": {**document["registry"], "report_id": report_id}}
        written["files"] = write_report(written["document"], output_dir, name, json_path)
        return written["files"]

    report_id = registry.record_report(task.task_id, document, report_paths(output_dir, name, json_path),
                                       train.id if train else None, priced.id if priced.kind == "eval" else None,
                                       write_files=write_files)
    return ReportOutcome(written["document"], written["files"], report_id, train, ctx.eval_run)


def report_after_training(registry: Registry, request: TrainRequest, train_id: int, eval_id: int | None,
                          output_dir: str | Path, json_path: str | Path | None, policy: PricingPolicy) -> ReportOutcome:
    """:func:`report_from_registry` for runs just recorded; failures say how to retry from the registry."""
    try:
        train = registry.run(train_id)
        priced = registry.run(eval_id) if eval_id is not None else train
        return report_from_registry(registry, request.task, priced, train, output_dir, json_path, policy)
    except (KeyboardInterrupt, SystemExit):
        raise
    except Exception as exc:
        kind = RegistryError if isinstance(exc, RegistryError) else BackendError
        raise kind(f"the report failed after training: {exc}. The trained run #{train_id} is in the registry; "
                   f"report from it with: {how_to_report_from(train_id, request.task.task_id, registry)}") from exc
