"""The report document: one versioned JSON-ready dict that every rendering reads.

Schema ``econmotor.task_pricing_report`` version :data:`REPORT_SCHEMA_VERSION`::

    schema, schema_version, generated_at, econmotor_version
    task:        task_id, description, unit, error_definition
    backend, objective {name, weights..., overlay, J}, datapacks [ids], datapack_objective_hints {id: hint}, notes
    runs:        train {run_id, status, seed, num_envs, max_steps, policy_path, ...} | null,
                 eval {...} | null   (the run whose episodes were priced: ``runs.priced``)
    verdict:     {deployable, label, reasons [..], checks [{name, measured, bound, limit, passed, text}],
                 acceptance {max_error_rate, min_units_per_hour, error_name, sources}}
    uncertainty: {confidence, interval_coverage, resamples, seed,
                  evidence {episodes, units_attempted, units_completed, errors, episodes_with_errors, robot_hours},
                  intervals {field: {point, low, high, method}}, conservative {TaskPrice fields}}
    recommendation: null when not deployable, else {price_usd_per_unit, price_usd_per_100_units,
                 price_usd_per_robot_hour, point_price_usd_per_unit, interval_usd_per_unit [low, high], basis}
    inputs:      [{name, value, unit, source}]  every number the price depends on
    pricing:     spread_share, aggregate {TaskPrice fields: point estimates, diagnostics},
                 distributions {field: {mean, p10, p50, p90, n}}, units {field: unit}
    metrics:     raw {..}, econ {..}  (aggregate over the priced episodes)
    episodes:    [{episode_index, termination_reason, mpl_units_per_hour, ..., J}]
    training_curve: [{timesteps, mean_return}]
    selection:   null, or the training run's evaluation-driven selection (motor_backend/selection.py):
                 {why, kept_env_steps, kept_acceptable, became_deployable {env_steps, wall_s} | null,
                  evaluation_cost {count, episodes, env_steps, wall_s}, held_out_seeds [first, end),
                  priced_seeds [first, end) | null, fresh_seeds, look_episodes,
                  conditions [names] | null}: which checkpoint was kept and why, whether the priced episodes
                 are apart from the held-out ones the checkpoint was chosen on, and under which conditions
                 the held-out episodes ran (the run record's ``selection_conditions``: episode i under [i % len])
    started_from: null, or what the training run's actor started from (``--init-policy``, the mjx
                 backend's ``init_policy`` record): {policy, sha256, hidden_sizes, activation,
                 critic_warmup_iterations}
    learned_with: null, or the reward the training run's learner saw, where the backend records it (the
                 mujoco backend's walker trainer): {econ_gain, objective_weights {term: weight}, per_wh,
                 locomotion {term: weight}, datapack_ids}: econ_gain times each step's increment of the
                 objective's J (this report's J; per_wh: its reward per Wh drawn), beside the locomotion terms
    evaluation:  how the episode count was chosen and why the evaluation stopped: {rule: sequential |
                 fixed | after training, episodes, and for a sequential one method, plan {batch, max_episodes,
                 max_wall_s, looks, look_confidence}, looks [{episodes, outcome, why, wall_s}], outcome
                 (pass, fail, episode cap, time cap), why, confidence (the verdict's), wall_s}
    registry:    {db_url, report_id}

JSON has no infinity: non-finite numbers are written as ``null`` (a robot that
completed nothing has no finite unit cost); ``json_ready`` does that conversion.

``objective.J``: the RewardBuilder J of each priced episode under the run's objective
(weights ``[mpl, error, energy, safety, novelty]``, energy in Wh or, with the objective's
``energy_term: usd``, in USD), computed by ``econmotor.objectives.loader.objective_j`` (``episode_j``
with the objective's energy term) — the same J shadow mode logs and ``econmotor solve`` ranks runs by,
and held-out selection keeps a checkpoint by. Datapack objective hints are shown as written (a preset
name or free text).
"""

from __future__ import annotations

import datetime as dt
import math
from dataclasses import dataclass, field
from typing import Any

from econmotor.economics.pricing import PricingSummary, pricing_inputs
from econmotor.economics.uncertainty import CONFIDENCE, Uncertainty, Verdict, judge
from econmotor.objectives import compile_economic_overlay
from econmotor.objectives.economic_objective import EconomicObjectiveSpec
from econmotor.objectives.loader import objective_j, objective_weights_vector
from econmotor.valuation.reward_builder import REWARD_TERM_NAMES

REPORT_SCHEMA = "econmotor.task_pricing_report"
# 2: TaskPrice gained damage_usd_per_unit, customer_saving_after_damage_usd_per_hour
# 3: verdict, uncertainty, recommendation; TaskPrice's recommended_price_* became price_* (point estimates)
REPORT_SCHEMA_VERSION = 3

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
def selection_facts(train_run: Any, priced: Any, num_episodes: int) -> dict[str, Any] | None:
    """The document's ``selection`` (module docstring) from the training run's recorded config."""
    config = (getattr(train_run, "config", None) or {}).get("backend_config") or {}
    selection = config.get("selection")
    if not selection:
        return None
    held_out = list(selection["seeds"])
    priced_seeds = [priced.seed, priced.seed + num_episodes] if priced is not None and priced.kind == "eval" \
        and priced.seed is not None else None
    fresh = None if priced_seeds is None else (priced_seeds[1] <= held_out[0] or priced_seeds[0] >= held_out[1])
    kept = selection.get("kept") or {}
    return {"why": selection["why"], "kept_env_steps": kept.get("env_steps"),
            "kept_acceptable": selection.get("kept_acceptable"),
            "became_deployable": selection.get("became_deployable"),
            "evaluation_cost": selection.get("evaluation_cost"), "held_out_seeds": held_out,
            "priced_seeds": priced_seeds, "fresh_seeds": fresh,
            "look_episodes": (selection.get("sequential") or {}).get("batch"),
            "conditions": config.get("selection_conditions")}


def started_from(train_run: Any) -> dict[str, Any] | None:
    """The document's ``started_from`` (module docstring) from the training run's recorded config."""
    config = (getattr(train_run, "config", None) or {}).get("backend_config") or {}
    init = config.get("init_policy")
    if not init:
        return None
    return {k: init.get(k) for k in ("policy", "sha256", "hidden_sizes", "activation", "critic_warmup_iterations")}


def learned_with(train_run: Any) -> dict[str, Any] | None:
    """The document's ``learned_with`` (module docstring) from the training run's recorded config."""
    config = (getattr(train_run, "config", None) or {}).get("backend_config") or {}
    if "econ_gain" not in config or "objective_weights" not in config:
        return None
    gain, weights = float(config["econ_gain"]), dict(zip(REWARD_TERM_NAMES, config["objective_weights"], strict=True))
    priced = (config.get("objective") or {}).get("energy_term") == "usd"
    usd_per_wh = float((config.get("economics") or {}).get("energy_price_usd_per_kwh", 0.0)) / 1000.0
    return {"econ_gain": gain, "objective_weights": weights,
            "per_wh": -gain * float(weights["r_energy"]) * (usd_per_wh if priced else 1.0),
            "locomotion": {k: v.get("weight") for k, v in (config.get("locomotion_rewards") or {}).items()},
            "datapack_ids": list(config.get("datapack_ids") or [])}


def recommendation(verdict: Verdict, uncertainty: Uncertainty, spread_share: float) -> dict[str, Any] | None:
    """The price to charge, at the unfavourable end of the intervals; ``None`` when not deployable."""
    if not verdict.deployable:
        return None
    cons, price = uncertainty.conservative, uncertainty.intervals["price_usd_per_unit"]
    pct = f"{uncertainty.confidence:.0%}"
    return {"price_usd_per_unit": cons.price_usd_per_unit,
            "price_usd_per_100_units": cons.price_usd_per_unit * 100,
            "price_usd_per_robot_hour": cons.price_usd_per_robot_hour,
            "point_price_usd_per_unit": price.point, "interval_usd_per_unit": [price.low, price.high],
            "customer_saving_usd_per_hour": cons.customer_saving_usd_per_hour,
            "basis": (f"priced at the unfavourable end of the intervals: throughput at its {pct} lower bound, "
                      f"error rate and energy at their {pct} upper bounds (robot unit cost "
                      f"{cons.robot_unit_cost_usd:.4g} USD), spread share {spread_share:g}")}


def acceptance_inputs(verdict: Verdict) -> list[dict[str, Any]]:
    """The acceptance limits as input rows (value, unit, source)."""
    acc = verdict.acceptance
    return [{"name": "acceptance_max_error_rate", "value": acc.max_error_rate, "unit": "errors/attempted unit",
             "source": acc.sources.get("max_error_rate", "")},
            {"name": "acceptance_min_units_per_hour", "value": acc.min_units_per_hour, "unit": "units/h",
             "source": acc.sources.get("min_units_per_hour", "")}]


def evaluation_facts(priced: Any, num_episodes: int) -> dict[str, Any]:
    """How the priced run's episode count was chosen and why its evaluation stopped (the document's
    ``evaluation``): ``rule`` "sequential" (with the run's recorded ``sequential``: method, plan, looks,
    outcome, why, confidence, wall_s), "fixed" (``--eval-episodes N``) or "after training"."""
    config = getattr(priced, "config", None) or {}
    sequential = (config.get("backend_config") or {}).get("sequential")
    if sequential:
        return {"rule": "sequential", "episodes": num_episodes, **sequential}
    if getattr(priced, "kind", None) == "eval":
        return {"rule": "fixed", "episodes": num_episodes}
    return {"rule": "after training", "episodes": num_episodes}


def assess_context(ctx: ReportContext) -> tuple[Uncertainty, Verdict]:
    """Intervals and the deployability verdict of the priced episodes. The intervals are at the report's
    confidence; a sequential evaluation's verdict is judged as its looks were (the bounds that stay valid
    under its optional stopping, :class:`~econmotor.economics.sequential_rule.SequentialPlan`)."""
    args = (ctx.task.economics, ctx.task.acceptance, ctx.task.unit, ctx.episodes, ctx.pricing.aggregate,
            ctx.pricing.policy)
    uncertainty, verdict = judge(*args)
    facts = evaluation_facts(ctx.eval_run or ctx.train_run, len(ctx.episodes))
    if facts["rule"] == "sequential":  # the look's bootstrap confidence, the plan's for the error rate's sequence
        plan_confidence = (facts.get("plan") or {}).get("confidence", CONFIDENCE)
        verdict = judge(*args, confidence=float(facts["confidence"]), sequential=True,
                        sequence_confidence=float(plan_confidence))[1]
    return uncertainty, verdict


def build_document(ctx: ReportContext, generated_at: dt.datetime | None = None) -> dict[str, Any]:
    """The report document (schema in the module docstring), JSON-ready."""
    import econmotor

    priced = ctx.eval_run or ctx.train_run
    vector = objective_weights_vector(ctx.objective)
    js = [objective_j(ctx.objective, ep, ctx.task.economics) for ep in ctx.episodes]
    unc, verdict = assess_context(ctx)
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
                      "J": {"vector": vector, "energy_term": ctx.objective.energy_term,
                            "mean": sum(js) / len(js) if js else None}},
        "datapacks": list(ctx.datapack_ids),
        "datapack_objective_hints": _objective_hints(ctx.train_run or ctx.eval_run),
        "notes": ctx.notes,
        "runs": {"train": _run_facts(ctx.train_run), "eval": _run_facts(ctx.eval_run),
                 "priced": priced.id if priced is not None else None},
        "verdict": verdict.to_dict(),
        "uncertainty": unc.to_dict(),
        "recommendation": recommendation(verdict, unc, ctx.pricing.policy.spread_share),
        "inputs": pricing_inputs(ctx.task.economics, ctx.pricing.policy, ctx.pricing.aggregate, source)
        + acceptance_inputs(verdict),
        "pricing": ctx.pricing.to_dict(),
        "metrics": {"raw": ctx.raw_metrics, "econ": ctx.econ_metrics},
        "episodes": [{**{k: ep.get(k) for k in EPISODE_FIELDS if k in ep}, "J": j}
                     for ep, j in zip(ctx.episodes, js, strict=True)],
        "training_curve": list(ctx.training_curve),
        "selection": selection_facts(ctx.train_run, priced, len(ctx.episodes)),
        "started_from": started_from(ctx.train_run),
        "learned_with": learned_with(ctx.train_run),
        "evaluation": evaluation_facts(priced, len(ctx.episodes)),
        "registry": {"db_url": ctx.db_url, "report_id": None},
    }
    return json_ready(doc)
