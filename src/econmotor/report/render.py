"""Render the report document as table rows (for rich), JSON, Markdown and self-contained HTML.

:func:`write_report` writes ``<name>.json``, ``<name>.md`` (with ``<name>_plots/*.png``
beside it) and ``<name>.html`` (plots embedded as base64 PNG, no external resources).
Every file is written to a temporary name in the same directory and renamed into
place, so a reader never sees half a report.
"""

from __future__ import annotations

import base64
import html
import json
import math
import os
import re
import tempfile
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from econmotor.config.acceptance import ERROR_RATE_CHECK
from econmotor.motor_backend.results import PROVENANCE_KEY
from econmotor.motor_backend.selection import evaluation_cost_text
from econmotor.report.plots import render_plots

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


_MD_SPECIAL = re.compile(r"([\\`*\[\]|])")


def md_escape(value: Any) -> str:
    """User text made inert in Markdown, as ``html.escape`` does for HTML: markup (``<script>``,
    ``<img onerror>``) is escaped, Markdown syntax is backslash-escaped, newlines become spaces."""
    text = html.escape(" ".join(str(value).split()), quote=False)
    return _MD_SPECIAL.sub(r"\\\1", text)


def _md_table(header: tuple[str, ...], rows: list[tuple[str, ...]]) -> str:
    lines = ["| " + " | ".join(md_escape(h) for h in header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(md_escape(c) for c in row) + " |" for row in rows]
    return "\n".join(lines)


def _run_line(run: Mapping[str, Any] | None) -> str:
    if not run:
        return "none"
    facts = [run["kind"], run["status"], f"seed {run['seed']}"]
    facts += [f"{k} {run[k]:,}" for k in ("num_envs", "max_steps") if run.get(k) is not None]
    if run.get("parent_run_id") is not None:
        facts.append(f"of run #{run['parent_run_id']}")
    return f"#{run['run_id']} ({', '.join(facts)}; policy {run['policy_path']})"


def _with_hint(pack_id: str, hints: Mapping[str, str]) -> str:
    return f"{pack_id} (objective hint: {hints[pack_id]})" if pack_id in hints else pack_id


def _j_line(j: Mapping[str, Any] | None) -> str:
    if not j or j.get("mean") is None:
        return "-"
    weights = ", ".join(f"{w:g}" for w in j["vector"])
    return f"{fmt(j['mean'])} mean per episode (weights [{weights}] on mpl, error, energy Wh, safety, novelty)"


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
    return text


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
    return (f"the objective's overlay x {fmt(seen['econ_gain'])} (reward per unit {fmt(seen['per_unit'])}, per Wh "
            f"{fmt(seen['per_wh'])}, per error {fmt(seen['per_error'])}) beside the locomotion terms ({terms}), "
            f"under {packs}")


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


def _sections(doc: Mapping[str, Any]) -> dict[str, Any]:
    """Shared content of Markdown and HTML."""
    task, obj = doc["task"], doc["objective"]
    overlay = ", ".join(f"{k}: {v:+g}" for k, v in obj["overlay"].items()) or "none"
    facts = [("task", f"{task['task_id']} — {task['description']}"), ("unit of work", task["unit"]),
             ("errors", task["error_definition"]), ("backend", doc["backend"]),
             ("objective", f"{obj['name']} (overlay {overlay})"),
             ("datapacks", ", ".join(_with_hint(d, doc.get("datapack_objective_hints") or {})
                                     for d in doc["datapacks"]) or "none"),
             ("objective J", _j_line(doc["objective"].get("J"))),
             ("training run", _run_line(doc["runs"]["train"])), ("evaluation run", _run_line(doc["runs"]["eval"])),
             ("registry", doc["registry"]["db_url"]), ("generated", doc["generated_at"])]
    evaluated = imported_policy_text(doc["runs"]["eval"])
    if evaluated:
        facts.insert(facts.index(("evaluation run", _run_line(doc["runs"]["eval"]))) + 1, ("evaluated", evaluated))
    kept = selection_text(doc.get("selection"))
    if kept:
        facts.insert(facts.index(("training run", _run_line(doc["runs"]["train"]))) + 1, ("policy kept", kept))
    seen = learned_with_text(doc.get("learned_with"))
    if seen:
        facts.insert(facts.index(("training run", _run_line(doc["runs"]["train"]))) + 1, ("learned with", seen))
    start = started_from_text(doc.get("started_from"))
    if start:
        facts.insert(facts.index(("training run", _run_line(doc["runs"]["train"]))) + 1, ("started from", start))
    if doc.get("notes"):
        facts.insert(0, ("notes", doc["notes"]))
    inputs = [(r["name"], fmt(r["value"]), r["unit"], r["source"]) for r in doc["inputs"]]
    ep_keys = ("episode_index", "termination_reason", "units_completed", "errors", "mpl_units_per_hour",
               "error_rate", "energy_wh", "robot_unit_cost_usd")
    episodes = [tuple(fmt(ep.get(k)) for k in ep_keys) for ep in doc["episodes"][:50]]
    return {"facts": facts, "inputs": inputs, "ep_keys": ep_keys, "episodes": episodes}


PRICING_NOTE = ("`aggregate` pools all evaluation episodes (the point estimate); the 90% interval's ends are "
                "one-sided 95% bounds (Clopper-Pearson for the error rate, a seeded bootstrap over episodes "
                "otherwise); mean and p10/p50/p90 are over episodes.")


def verdict_rows(doc: Mapping[str, Any]) -> list[tuple[str, str, str]]:
    """(check, passed, what was measured) for every acceptance check."""
    return [(c["name"], "pass" if c["passed"] else "FAIL", c["text"]) for c in doc["verdict"]["checks"]]


def _md_verdict(doc: Mapping[str, Any]) -> list[str]:
    verdict = doc["verdict"]
    lines = [f"## Verdict: {verdict['label']}", "", _md_table(("check", "result", "measured"), verdict_rows(doc)),
             ""]
    rec = doc.get("recommendation")
    if rec:
        lines += [f"Recommended price: **{fmt(rec['price_usd_per_unit'])} USD per {doc['task']['unit']}**, "
                  f"{fmt(rec['price_usd_per_100_units'])} USD per 100, {fmt(rec['price_usd_per_robot_hour'])} USD "
                  f"per robot-hour; {rec['basis']}.", ""]
    return lines


PLOT_TITLES = {"unit_costs": "Human vs robot unit cost", "episode_distributions": "Per-episode distributions",
               "training_curve": "Training curve"}


def render_markdown(doc: Mapping[str, Any], plot_files: Mapping[str, str] | None = None) -> str:
    """The Markdown report; ``plot_files`` maps plot name -> relative image path."""
    s = _sections(doc)
    parts = [f"# Task pricing report: {md_escape(doc['task']['task_id'])}", "", f"**{md_escape(headline(doc))}**", "",
             _md_table(("", ""), [(k, v) for k, v in s["facts"]]), "",
             *_md_verdict(doc),
             f"## {'Diagnostics' if not doc['verdict']['deployable'] else 'Pricing'} "
             f"(spread share {fmt(doc['pricing']['spread_share'])})", "", f"{PRICING_NOTE}", "",
             _md_table(("metric", STAT_COLUMNS[0], INTERVAL_COLUMN, *STAT_COLUMNS[1:], "unit"), table_rows(doc)), "",
             "## Inputs", "", _md_table(("parameter", "value", "unit", "source"), s["inputs"]), ""]
    for name, path in (plot_files or {}).items():
        parts += [f"## {PLOT_TITLES.get(name, name)}", "", f"![{name}]({path})", ""]
    parts += ["## Evaluation episodes", "", _md_table(s["ep_keys"], s["episodes"]), "",
              f"_Document schema {doc['schema']} v{doc['schema_version']}._", ""]
    return "\n".join(parts)


_CSS = """body{font-family:system-ui,-apple-system,Segoe UI,Helvetica,Arial,sans-serif;margin:2rem auto;
max-width:1100px;color:#222;padding:0 1rem}h1{margin-bottom:.2rem}h2{border-bottom:1px solid #ddd;
padding-bottom:.2rem;margin-top:2rem}.headline{font-size:1.15rem;background:#eef6ee;border-left:4px solid #2ca02c;
padding:.7rem 1rem}.verdict{font-size:1.4rem;font-weight:700;color:#2ca02c;margin:.3rem 0}
.verdict.bad{color:#d62728;background:none}.bad{background:#fbeeee;border-color:#d62728}
table{border-collapse:collapse;margin:.5rem 0;
font-size:.92rem}td,th{border:1px solid #ddd;padding:.3rem .6rem;text-align:left}th{background:#f5f5f5}
td.num{text-align:right;font-variant-numeric:tabular-nums;white-space:nowrap}img{max-width:100%;margin:.5rem 0}
.facts td:first-child{font-weight:600;white-space:nowrap}small{color:#666}"""


def _html_table(header: tuple[str, ...] | None, rows: list[tuple[str, ...]], cls: str = "",
                numeric_from: int = 99) -> str:
    out = [f'<table class="{cls}">']
    if header:
        out.append("<tr>" + "".join(f"<th>{html.escape(h)}</th>" for h in header) + "</tr>")
    for row in rows:
        cells = [f'<td{" class=num" if i >= numeric_from else ""}>{html.escape(str(c))}</td>'
                 for i, c in enumerate(row)]
        out.append("<tr>" + "".join(cells) + "</tr>")
    out.append("</table>")
    return "\n".join(out)


def render_html(doc: Mapping[str, Any], plots: Mapping[str, bytes]) -> str:
    """A self-contained HTML page: inline CSS, plots as base64 PNG data URIs."""
    s = _sections(doc)
    agg, verdict = doc["pricing"]["aggregate"], doc["verdict"]
    good = verdict["deployable"] and agg.get("competitive") and (agg.get("implied_wage_usd_per_hour") or 0.0) >= 0
    rec = doc.get("recommendation")
    body = [f"<h1>Task pricing report: {html.escape(doc['task']['task_id'])}</h1>",
            f'<p class="verdict{"" if verdict["deployable"] else " bad"}">{html.escape(verdict["label"].upper())}</p>',
            f'<p class="headline{"" if good else " bad"}">{html.escape(headline(doc))}</p>',
            f"<h2>Verdict: {html.escape(verdict['label'])}</h2>",
            _html_table(("check", "result", "measured"), verdict_rows(doc))]
    if rec:
        body.append(f"<p>Recommended price: <b>{html.escape(fmt(rec['price_usd_per_unit']))} USD per "
                    f"{html.escape(doc['task']['unit'])}</b>, {html.escape(fmt(rec['price_usd_per_100_units']))} "
                    f"USD per 100, {html.escape(fmt(rec['price_usd_per_robot_hour']))} USD per robot-hour; "
                    f"{html.escape(rec['basis'])}.</p>")
    body += [_html_table(None, s["facts"], "facts"),
             (f"<h2>{'Diagnostics' if not verdict['deployable'] else 'Pricing'} <small>(spread share "
              f"{fmt(doc['pricing']['spread_share'])}; {html.escape(PRICING_NOTE.replace('`', ''))})</small></h2>"),
             _html_table(("metric", STAT_COLUMNS[0], INTERVAL_COLUMN, *STAT_COLUMNS[1:], "unit"), table_rows(doc),
                         numeric_from=1)]
    for name, png in plots.items():
        data = base64.b64encode(png).decode("ascii")
        body += [f"<h2>{html.escape(PLOT_TITLES.get(name, name))}</h2>",
                 f'<img alt="{html.escape(name)}" src="data:image/png;base64,{data}">']
    body += ["<h2>Inputs</h2>", _html_table(("parameter", "value", "unit", "source"), s["inputs"]),
             "<h2>Evaluation episodes</h2>", _html_table(s["ep_keys"], s["episodes"], numeric_from=2),
             f"<p><small>Document schema {html.escape(doc['schema'])} v{doc['schema_version']}.</small></p>"]
    title = html.escape(f"econmotor pricing: {doc['task']['task_id']}")
    return (f'<!DOCTYPE html>\n<html lang="en"><head><meta charset="utf-8"><title>{title}</title>'
            f"<style>{_CSS}</style></head><body>\n" + "\n".join(body) + "\n</body></html>\n")


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def atomic_write(path: str | Path, data: bytes | str) -> Path:
    """Write ``data`` to a temporary file beside ``path`` and rename it into place."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    raw = data.encode("utf-8") if isinstance(data, str) else data
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        os.chmod(tmp, 0o666 & ~_umask())  # mkstemp makes 0600; a report is meant to be read
        with os.fdopen(fd, "wb") as fh:
            fh.write(raw)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path


def report_paths(output_dir: str | Path, name: str = "report", json_path: str | Path | None = None) -> dict[str, str]:
    """Where :func:`write_report` puts the JSON, Markdown and HTML files."""
    out = Path(output_dir)
    return {"json": str(Path(json_path) if json_path else out / f"{name}.json"),
            "markdown": str(out / f"{name}.md"), "html": str(out / f"{name}.html")}


def write_report(doc: Mapping[str, Any], output_dir: str | Path, name: str = "report",
                 json_path: str | Path | None = None) -> dict[str, str]:
    """Write the JSON, Markdown (+ PNG plots) and HTML reports; returns kind -> path."""
    out = Path(output_dir)
    plots = render_plots(dict(doc))
    plot_dir = f"{name}_plots"
    plot_files = {}
    for plot_name, png in plots.items():
        atomic_write(out / plot_dir / f"{plot_name}.png", png)
        plot_files[plot_name] = f"{plot_dir}/{plot_name}.png"
    files = report_paths(output_dir, name, json_path)
    atomic_write(files["json"], json.dumps(doc, indent=2, allow_nan=False) + "\n")
    atomic_write(files["markdown"], render_markdown(doc, plot_files))
    atomic_write(files["html"], render_html(doc, plots))
    return files
