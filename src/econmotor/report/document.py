"""The report document: one versioned JSON-ready dict that every rendering reads.

Schema ``econmotor.task_pricing_report`` version :data:`REPORT_SCHEMA_VERSION`::

    schema, schema_version, generated_at, econmotor_version
    task:        task_id, description, unit, error_definition
    backend, objective {name, weights..., overlay, J}, datapacks [ids], datapack_objective_hints {id: hint}, notes
    runs:        train {run_id, status, seed, num_envs, max_steps, policy_path, ...} | null,
                 eval {...} | null   (the run whose episodes were priced: ``runs.priced``)
    inputs:      [{name, value, unit, source}]  every number the price depends on
    pricing:     spread_share, aggregate {TaskPrice fields}, distributions {field: {mean, p10, p50, p90, n}},
                 units {field: unit}
    metrics:     raw {..}, econ {..}  (aggregate over the priced episodes)
    episodes:    [{episode_index, termination_reason, mpl_units_per_hour, ..., J}]
    training_curve: [{timesteps, mean_return}]
    registry:    {db_url, report_id}

JSON has no infinity: non-finite numbers are written as ``null`` (a robot that
completed nothing has no finite unit cost); ``json_ready`` does that conversion.

``objective.J``: the RewardBuilder J of each priced episode under the run's objective
(weights ``[mpl, error, energy, safety, novelty]``, energy in Wh), computed by
``econmotor.valuation.episode_j`` — the same J shadow mode logs and ``econmotor solve``
ranks runs by. Datapack objective hints are shown as written (a preset name or free text).
"""

from __future__ import annotations

import datetime as dt
import math
from dataclasses import dataclass, field
from typing import Any

from econmotor.economics.pricing import PricingSummary, pricing_inputs
from econmotor.objectives import compile_economic_overlay
from econmotor.objectives.economic_objective import EconomicObjectiveSpec
from econmotor.objectives.loader import objective_weights_vector
from econmotor.valuation.reward_builder import episode_j

REPORT_SCHEMA = "econmotor.task_pricing_report"
REPORT_SCHEMA_VERSION = 2  # 2: TaskPrice gained damage_usd_per_unit, customer_saving_after_damage_usd_per_hour

#: per-episode fields copied into the document (and its episode table).
EPISODE_FIELDS = ("episode_index", "termination_reason", "units_completed", "errors", "episode_length_s",
                  "mpl_units_per_hour", "error_rate", "energy_wh", "energy_wh_per_unit",
                  "implied_wage_usd_per_hour", "wage_parity", "robot_unit_cost_usd", "risk_score",
                  "novelty_score", "return")


@dataclass(frozen=True)
class ReportContext:
    """Everything a report is made of (gathered by the CLI from a fresh or recorded run).

    Attributes:
        task: the ``TaskSpec`` priced.
        backend: backend factory name that produced the runs.
        objective: the objective trained under.
        datapack_ids: datapacks used, in order.
        pricing: the priced evaluation.
        raw_metrics / econ_metrics: aggregate metrics of the priced episodes.
        episodes: per-episode summaries of the priced evaluation.
        train_run / eval_run: registry run facts (``RunRecord``) or ``None``.
        training_curve: ``[{"timesteps", "mean_return"}]``.
        notes: free text from ``--notes``.
        db_url: the registry URL (password hidden).
    """

    task: Any
    backend: str
    objective: EconomicObjectiveSpec
    datapack_ids: tuple[str, ...]
    pricing: PricingSummary
    raw_metrics: dict[str, Any]
    econ_metrics: dict[str, Any]
    episodes: list[dict[str, Any]]
    train_run: Any = None
    eval_run: Any = None
    training_curve: list[dict[str, Any]] = field(default_factory=list)
    notes: str = ""
    db_url: str = ""


def json_ready(value: Any) -> Any:
    """Deep copy with non-finite floats as ``None`` and tuples as lists (strict JSON)."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {str(k): json_ready(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [json_ready(v) for v in value]
    if hasattr(value, "item") and not isinstance(value, (str, bytes)):
        return json_ready(value.item())
    return value


def _run_facts(run: Any) -> dict[str, Any] | None:
    if run is None:
        return None
    return {"run_id": run.id, "kind": run.kind, "status": run.status, "seed": run.seed,
            "num_envs": run.num_envs, "max_steps": run.max_steps, "policy_path": run.policy_path,
            "parent_run_id": run.parent_run_id, "objective_name": run.objective_name,
            "datapack_ids": list(run.datapack_ids), "config": run.config, "artifacts": run.artifacts,
            "created_at": run.created_at.isoformat() if run.created_at else None,
            "finished_at": run.finished_at.isoformat() if run.finished_at else None}


def _objective_hints(run: Any) -> dict[str, str]:
    """Datapack id -> objective hint (a preset name or free text) from the run's recorded datapacks."""
    packs = (getattr(run, "config", None) or {}).get("datapacks") or []
    return {str(p["id"]): str(p["objective_hint"]) for p in packs
            if isinstance(p, dict) and p.get("id") and p.get("objective_hint")}


def build_document(ctx: ReportContext, generated_at: dt.datetime | None = None) -> dict[str, Any]:
    """The report document (schema in the module docstring), JSON-ready."""
    import econmotor

    priced = ctx.eval_run or ctx.train_run
    vector = objective_weights_vector(ctx.objective)
    js = [episode_j(ep, vector, ctx.task.economics) for ep in ctx.episodes]
    source = (f"measured: {priced.kind} run #{priced.id} of the registry, {len(ctx.episodes)} episodes"
              if priced is not None else f"measured: {len(ctx.episodes)} evaluation episodes")
    doc = {
        "schema": REPORT_SCHEMA,
        "schema_version": REPORT_SCHEMA_VERSION,
        "generated_at": (generated_at or dt.datetime.now(dt.UTC)).isoformat(),
        "econmotor_version": getattr(econmotor, "__version__", "unknown"),
        "task": {"task_id": ctx.task.task_id, "description": ctx.task.description, "unit": ctx.task.unit,
                 "error_definition": ctx.task.error_definition},
        "backend": ctx.backend,
        "objective": {**ctx.objective.to_dict(), "overlay": compile_economic_overlay(ctx.objective).to_dict(),
                      "J": {"vector": vector, "energy_term": "wh", "mean": sum(js) / len(js) if js else None}},
        "datapacks": list(ctx.datapack_ids),
        "datapack_objective_hints": _objective_hints(ctx.train_run or ctx.eval_run),
        "notes": ctx.notes,
        "runs": {"train": _run_facts(ctx.train_run), "eval": _run_facts(ctx.eval_run),
                 "priced": priced.id if priced is not None else None},
        "inputs": pricing_inputs(ctx.task.economics, ctx.pricing.policy, ctx.pricing.aggregate, source),
        "pricing": ctx.pricing.to_dict(),
        "metrics": {"raw": ctx.raw_metrics, "econ": ctx.econ_metrics},
        "episodes": [{**{k: ep.get(k) for k in EPISODE_FIELDS if k in ep}, "J": j}
                     for ep, j in zip(ctx.episodes, js, strict=True)],
        "training_curve": list(ctx.training_curve),
        "registry": {"db_url": ctx.db_url, "report_id": None},
    }
    return json_ready(doc)
