"""The report in words: numbers for people, the pricing table's rows and the report's sentences.

What the console (``econmotor report``'s rich tables), the Markdown and the HTML report all show,
read from the report document (:mod:`econmotor.report.document`): :func:`fmt` (a number to 4
significant digits, ``n/a`` for null or infinite), the pricing table's rows (:func:`table_rows`:
aggregate, 90% interval, mean, p10/p50/p90 and unit of every priced figure), the acceptance checks
(:func:`verdict_rows`), the headline (:func:`headline`: the verdict first, then what to charge) and
the one-sentence accounts of the evidence, the checkpoint kept, a fine-tune's start, the reward
learned with and how the evaluation's figures were made. The documents and files are
:mod:`econmotor.report.render`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

from econmotor.config.acceptance import ERROR_RATE_CHECK
from econmotor.motor_backend.results import PROVENANCE_KEY
from econmotor.motor_backend.selection import evaluation_cost_text

#: (field, label) of the pricing table, in reading order; every saving says what it counts.
PRICE_ROWS = (
    ("mpl_units_per_hour", "robot throughput (MPL)"),
    ("error_rate", "robot error rate"),
    ("energy_kwh_per_hour", "robot energy"),
    ("energy_productivity_units_per_kwh", "energy productivity"),
    ("implied_wage_usd_per_hour", "implied robot wage (value of its work minus damage)"),
    ("wage_parity", "wage parity (implied robot wage / human wage)"),
    ("human_unit_cost_usd", "human unit cost (wage / human throughput)"),
    ("robot_cost_usd_per_hour", "robot cost per hour (capex share, upkeep, energy)"),
    ("robot_unit_cost_usd", "robot unit cost (robot cost per hour / MPL)"),
    ("spread_per_unit_usd", "spread per unit (human - robot unit cost)"),
    ("price_usd_per_unit", "price per unit at the point estimate"),
    ("price_usd_per_robot_hour", "price per robot-hour at the point estimate"),
    ("customer_saving_usd_per_hour", "customer saving per robot-hour: human wage for the same work minus the "
                                     "price (damage not counted)"),
    ("damage_usd_per_unit", "expected damage per unit (damage cost x robot error rate)"),
    ("customer_saving_after_damage_usd_per_hour", "customer saving per robot-hour with damage: the above plus the "
                                                  "human's expected damage avoided, minus the robot's"),
    ("break_even_hours", "break-even hours of capex at the point-estimate price"),
)
#: (field, label) of a battery-powered robot's rows (economics/battery.py), after the energy rows; a
#: task without a battery has none of them.
BATTERY_ROWS = (
    ("battery_runtime_h", "runtime per charge (battery capacity / robot energy per hour)"),
    ("battery_units_per_charge", "units per charge (battery capacity / energy per unit)"),
    ("battery_charging_share", "share of paid robot-hours lost charging (charge / (runtime + charge))"),
    ("mpl_units_per_paid_hour", "robot throughput per paid robot-hour (MPL x (1 - share lost charging)); "
                                "the costs, wage and prices per hour below are per paid hour"),
)
STAT_COLUMNS = ("aggregate", "mean", "p10", "p50", "p90")
INTERVAL_COLUMN = "90% interval"


def fmt(value: Any) -> str:
    """A number for people: 4 significant digits, thousands separators, ``n/a`` for null/inf."""
    if value is None:
        return "n/a"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, (int, float)):
        if not math.isfinite(value):
            return "n/a"
        if abs(value) >= 1e15:
            return f"{value:.3e}"
        return f"{value:,.0f}" if abs(value) >= 1000 else f"{value:,.4g}"
    return str(value)


def interval_text(doc: Mapping[str, Any], key: str) -> str:
    """``"low - high"`` of a field's interval, or ``""`` when it has none."""
    iv = ((doc.get("uncertainty") or {}).get("intervals") or {}).get(key)
    if not iv:
        return ""
    return f"{fmt(iv['low'])} - {fmt(iv['high'])}"


def price_rows(aggregate: Mapping[str, Any]) -> tuple[tuple[str, str], ...]:
    """The pricing table's (field, label) rows: :data:`PRICE_ROWS`, with :data:`BATTERY_ROWS` after the
    energy rows when the robot runs on a battery."""
    if "battery_charging_share" not in aggregate:
        return PRICE_ROWS
    at = [key for key, _ in PRICE_ROWS].index("energy_productivity_units_per_kwh") + 1
    return PRICE_ROWS[:at] + BATTERY_ROWS + PRICE_ROWS[at:]


def table_rows(doc: Mapping[str, Any]) -> list[tuple[str, ...]]:
    """Rows ``(label, aggregate, 90% interval, mean, p10, p50, p90, unit)`` of the pricing table."""
    pricing = doc["pricing"]
    agg, dists, units = pricing["aggregate"], pricing.get("distributions") or {}, pricing["units"]
    rows = []
    stated = stated_runtime_text(doc)
    for key, label in price_rows(agg):
        dist = dists.get(key, {})
        if key == "battery_runtime_h" and stated:
            label = f"{label[:-1]}; {stated})"
        rows.append((label, fmt(agg.get(key)), interval_text(doc, key),
                     *(fmt(dist.get(s)) for s in STAT_COLUMNS[1:]), units[key]))
    return rows


def stated_runtime_text(doc: Mapping[str, Any]) -> str:
    """The maker's runtime per charge beside the metered one (the robot card's, recorded in the evaluation's
    provenance with its source), e.g. ``"the maker states 2 h of continuous operation"``; "" where no maker
    states one."""
    provenance = (((doc.get("runs") or {}).get("eval") or {}).get("config") or {}).get(PROVENANCE_KEY) or {}
    hours = provenance.get("stated_runtime_h")
    return f"the maker states {fmt(hours)} h of {provenance.get('stated_runtime')}" if hours else ""


def evidence_text(doc: Mapping[str, Any]) -> str:
    """What the figures rest on, in one sentence; then how the episode count was chosen and why the
    evaluation stopped."""
    ev = doc["uncertainty"]["evidence"]
    text = (f"Evidence: {ev['episodes']} evaluation episodes, {fmt(ev['units_attempted'])} units attempted "
            f"(unit: {doc['task']['unit']}), {fmt(ev['errors'])} {_errors_word(doc)}, {fmt(ev['robot_hours'])} "
            f"robot-hours ({fmt(ev['robot_hours'] * 60)} robot-minutes).")
    how = episodes_chosen_text(doc.get("evaluation"))
    return f"{text} {how}" if how else text


def episodes_chosen_text(evaluation: Mapping[str, Any] | None) -> str:
    """How the priced episode count was chosen and why the evaluation stopped, in one sentence."""
    if not evaluation:
        return ""
    if evaluation["rule"] == "fixed":
        return f"Episodes: a fixed {evaluation['episodes']}, as asked (--eval-episodes)."
    if evaluation["rule"] == "after training":
        return f"Episodes: the {evaluation['episodes']} evaluated right after training."
    plan, looks = evaluation["plan"], evaluation.get("looks") or []
    outcome = {"pass": "passed: every bound inside its limit", "fail": f"failed: {evaluation.get('why')}",
               }.get(evaluation["outcome"], f"{evaluation['outcome']}: {evaluation.get('why')}")
    return (f"Episodes: sequential, until the acceptance rule was decided (a look after every {plan['batch']} "
            f"episodes, at most {plan['max_episodes']}; the error rate's bounds a confidence sequence valid at every "
            f"look, the bootstrap bounds at {plan['look_confidence'] * 100:.3g}%: alpha-spending over the "
            f"{len(plan['looks'])} looks, so the verdict holds at {plan['confidence'] * 100:.3g}% however early it "
            f"stops); stopped after {evaluation['episodes']} episodes at look {len(looks)}, {outcome} "
            f"({fmt(evaluation.get('wall_s'))} s).")


def _errors_word(doc: Mapping[str, Any]) -> str:
    name = doc["verdict"]["acceptance"].get("error_name") or "error"
    return name if name.endswith("s") else f"{name}s"


def parity_text(doc: Mapping[str, Any]) -> str:
    """Wage parity in words."""
    agg = doc["pricing"]["aggregate"]
    parity, wage = agg.get("wage_parity"), agg.get("implied_wage_usd_per_hour")
    human = {i["name"]: i["value"] for i in doc.get("inputs", [])}.get("wage_human_usd_per_hour")
    iv = interval_text(doc, "wage_parity")
    within = f" (90% interval {iv})" if iv else ""
    if parity is None or wage is None:
        return ""
    if parity < 0:
        return (f"The robot's labour is worth less than nothing: damage from its errors exceeds the value of its "
                f"work (implied wage {fmt(wage)} USD/h against a human's {fmt(human)} USD/h).")
    return (f"The robot's labour is worth {parity:.3g}x a human's wage{within}: its work, net of damage, is "
            f"worth {fmt(wage)} USD per hour against a human's {fmt(human)} USD/h.")


def headline(doc: Mapping[str, Any]) -> str:
    """The verdict first; then, for a deployable robot only, what to charge, with its interval and evidence."""
    verdict, unit = doc["verdict"], doc["task"]["unit"]
    if not verdict["deployable"]:
        return (f"Not deployable: {'; '.join(verdict['reasons'])}. No price is recommended; the figures below "
                f"are diagnostics only. {evidence_text(doc)}")
    rec = doc["recommendation"]
    low, high = rec["interval_usd_per_unit"]
    err_check = next(c for c in verdict["checks"] if c["name"] == ERROR_RATE_CHECK)
    text = (f"Deployable: {err_check['text']}. Charge {fmt(rec['price_usd_per_unit'])} USD per {unit} "
            f"({fmt(rec['price_usd_per_100_units'])} USD per 100; {fmt(rec['price_usd_per_robot_hour'])} USD per "
            f"robot-hour), priced at the unfavourable end of the 90% intervals; the point estimate is "
            f"{fmt(rec['point_price_usd_per_unit'])} USD per {unit} (90% interval {fmt(low)} - {fmt(high)}). "
            f"{parity_text(doc)}")
    saving = rec.get("customer_saving_usd_per_hour")
    if saving is not None and saving >= 0:
        text += (f" At this price the customer saves {fmt(saving)} USD per robot-hour against paying a human for "
                 "the same work (wages only).")
    elif saving is not None:
        text += (f" At this price the robot is dearer than a human: the customer pays {fmt(-saving)} USD per "
                 "robot-hour more (wages only).")
    agg = doc["pricing"]["aggregate"]
    after = agg.get("customer_saving_after_damage_usd_per_hour")
    if after is not None and after < 0:
        text += (f" With damage of {fmt(agg.get('damage_usd_per_unit'))} USD per {unit} (human: "
                 f"{fmt(task_damage_per_unit(doc))} USD) the customer loses {fmt(-after)} USD/h against a human "
                 "worker at the point-estimate price.")
    return f"{text} {evidence_text(doc)}"


def task_damage_per_unit(doc: Mapping[str, Any]) -> float | None:
    """The human's expected damage per unit, ``c_d * e_h``, from the report's inputs."""
    inputs = {i["name"]: i["value"] for i in doc.get("inputs", [])}
    c_d, e_h = inputs.get("damage_cost_usd_per_error"), inputs.get("error_rate_human")
    return None if c_d is None or e_h is None else c_d * e_h


def selection_text(selection: Mapping[str, Any] | None) -> str | None:
    """Which checkpoint the training run kept and why, and whether the priced episodes are fresh."""
    if not selection:
        return None
    text = selection["why"]
    first = selection.get("became_deployable")
    if first:
        text += (f"; deployable on held-out episodes after {first['env_steps']:,} env steps "
                 f"({first['wall_s']:.0f} s)")
    cost = selection.get("evaluation_cost") or {}
    if cost:
        text += f"; {evaluation_cost_text(cost)}"
    seeds = selection["held_out_seeds"]
    if selection.get("fresh_seeds") is True:
        text += (f". The priced episodes (seeds {selection['priced_seeds'][0]}-{selection['priced_seeds'][1] - 1}) "
                 f"are apart from the held-out ones it was chosen on ({seeds[0]}-{seeds[1] - 1})")
    elif selection.get("fresh_seeds") is False:
        text += ". WARNING: the priced episodes share seeds with the held-out ones the checkpoint was chosen on"
    chosen = chosen_by_text(selection)
    return f"{text}. {chosen}" if chosen else text


def chosen_by_text(selection: Mapping[str, Any]) -> str | None:
    """Under which conditions the held-out episodes the checkpoint was chosen on ran, in one sentence (None
    where the run did not record them, or kept its last weights unjudged): episode i under
    ``conditions[i % len]``, seeded ``first + i``."""
    conditions, seeds = selection.get("conditions"), selection["held_out_seeds"]  # [first, first + cap)
    if not conditions or selection.get("kept_env_steps") is None:
        return None
    names = [str(c) for c in conditions]
    under = (f"under {names[0]} conditions" if len(names) == 1 else
             f"alternating {', '.join(names[:-1])} and {names[-1]} conditions episode by episode")
    look = selection.get("look_episodes")
    judged = f", judged every {look}," if look else ""
    return (f"Chosen by held-out evaluations of at most {seeds[1] - seeds[0]} episodes{judged} {under} "
            f"(seeds {seeds[0]}-{seeds[1] - 1})")


def started_from_text(start: Mapping[str, Any] | None) -> str | None:
    """What the training run's actor started from (``--init-policy``), or None for a fresh actor."""
    if not start:
        return None
    sizes = " -> ".join(str(h) for h in start.get("hidden_sizes") or [])
    return (f"{start['policy']} (sha256 {str(start.get('sha256'))[:12]}; actor {sizes}, {start.get('activation')}), "
            f"fine-tuned for this objective after {start.get('critic_warmup_iterations')} critic-only iterations")


def learned_with_text(seen: Mapping[str, Any] | None) -> str | None:
    """The reward the learner saw (the document's ``learned_with``), or None where the backend does not say."""
    if not seen:
        return None
    terms = ", ".join(f"{k} {fmt(v)}" for k, v in seen["locomotion"].items()) or "none"
    packs = ", ".join(seen["datapack_ids"]) or "nominal conditions"
    weights = ", ".join(f"{k.removeprefix('r_')} {fmt(v)}" for k, v in seen["objective_weights"].items())
    return (f"this report's J x {fmt(seen['econ_gain'])} (each step's increment of the episode's J; weights "
            f"{weights}; reward per Wh {fmt(seen['per_wh'])}) beside the locomotion terms ({terms}), under {packs}")


def imported_policy_text(eval_run: Mapping[str, Any] | None) -> str:
    """How an evaluation's figures were made, from its recorded provenance (``MotorEvalResult.provenance``):
    imported or not, the evaluator, and on a commanded course the speed achieved against the speed commanded;
    "" for an evaluation of a policy trained here that walks no course."""
    run = eval_run or {}
    provenance = (run.get("config") or {}).get(PROVENANCE_KEY) or {}
    commanded = provenance.get("commanded_speed_m_per_s")
    if commanded is None and not provenance.get("imported"):
        return ""
    policy = run.get("policy_path")
    origin = f"imported policy {policy} (trained elsewhere; nothing trained here)" if provenance.get("imported") \
        else f"policy {policy} trained here"
    speed = "" if commanded is None else (f"; speed achieved {fmt(provenance.get('achieved_speed_m_per_s'))} m/s "
                                          f"against {fmt(commanded)} m/s commanded, while walking")
    return f"{origin}; figures from {provenance.get('figures_from')}{speed}"


def verdict_rows(doc: Mapping[str, Any]) -> list[tuple[str, str, str]]:
    """(check, passed, what was measured) for every acceptance check."""
    return [(c["name"], "pass" if c["passed"] else "FAIL", c["text"]) for c in doc["verdict"]["checks"]]
