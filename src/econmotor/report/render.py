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

from econmotor.report.plots import render_plots

#: (field, label) of the pricing table, in reading order.
PRICE_ROWS = (
    ("mpl_units_per_hour", "robot throughput (MPL)"),
    ("error_rate", "robot error rate"),
    ("energy_kwh_per_hour", "robot energy"),
    ("energy_productivity_units_per_kwh", "energy productivity"),
    ("implied_wage_usd_per_hour", "implied robot wage"),
    ("wage_parity", "wage parity (robot / human)"),
    ("human_unit_cost_usd", "human unit cost"),
    ("robot_cost_usd_per_hour", "robot cost per hour"),
    ("robot_unit_cost_usd", "robot unit cost"),
    ("spread_per_unit_usd", "spread per unit"),
    ("recommended_price_usd_per_unit", "recommended price per unit"),
    ("recommended_price_usd_per_robot_hour", "recommended price per robot-hour"),
    ("customer_saving_usd_per_hour", "customer saving per hour"),
    ("damage_usd_per_unit", "expected damage per unit"),
    ("customer_saving_after_damage_usd_per_hour", "customer saving after damage"),
    ("break_even_hours", "break-even hours of capex"),
)
STAT_COLUMNS = ("aggregate", "mean", "p10", "p50", "p90")


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


def table_rows(doc: Mapping[str, Any]) -> list[tuple[str, ...]]:
    """Rows ``(label, aggregate, mean, p10, p50, p90, unit)`` of the pricing table."""
    pricing = doc["pricing"]
    agg, dists, units = pricing["aggregate"], pricing.get("distributions") or {}, pricing["units"]
    rows = []
    for key, label in PRICE_ROWS:
        dist = dists.get(key, {})
        rows.append((label, fmt(agg.get(key)), *(fmt(dist.get(s)) for s in STAT_COLUMNS[1:]), units[key]))
    return rows


def headline(doc: Mapping[str, Any]) -> str:
    """One sentence: what to charge and why."""
    agg, task = doc["pricing"]["aggregate"], doc["task"]
    unit = task["unit"]
    if agg.get("recommended_price_usd_per_unit") is None:
        return f"The robot completed no {unit} in evaluation: it cannot be priced per unit."
    verdict = ("cheaper than a human" if agg["competitive"] else "dearer than a human (not competitive)")
    text = (f"Charge {fmt(agg['recommended_price_usd_per_unit'])} USD per {unit} "
            f"({fmt(agg['recommended_price_usd_per_robot_hour'])} USD per robot-hour): the robot's unit cost is "
            f"{fmt(agg['robot_unit_cost_usd'])} USD vs {fmt(agg['human_unit_cost_usd'])} USD for a human, "
            f"{verdict}; wage parity {fmt(agg['wage_parity'])}.")
    if (agg.get("implied_wage_usd_per_hour") or 0.0) < 0:
        text += (f" Warning: at error rate {fmt(agg['error_rate'])} the damage from errors exceeds the value of "
                 f"the work (implied wage {fmt(agg['implied_wage_usd_per_hour'])} USD/h); the unit cost "
                 "counts the robot's own cost only.")
    after = agg.get("customer_saving_after_damage_usd_per_hour")
    if after is not None and after < 0:
        text += (f" With damage of {fmt(agg.get('damage_usd_per_unit'))} USD per {unit} (human: "
                 f"{fmt(task_damage_per_unit(doc))} USD) the customer loses {fmt(-after)} USD/h against a human "
                 "worker at this price.")
    return text


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
    if doc.get("notes"):
        facts.insert(0, ("notes", doc["notes"]))
    inputs = [(r["name"], fmt(r["value"]), r["unit"], r["source"]) for r in doc["inputs"]]
    ep_keys = ("episode_index", "termination_reason", "units_completed", "errors", "mpl_units_per_hour",
               "error_rate", "energy_wh", "robot_unit_cost_usd")
    episodes = [tuple(fmt(ep.get(k)) for k in ep_keys) for ep in doc["episodes"][:50]]
    return {"facts": facts, "inputs": inputs, "ep_keys": ep_keys, "episodes": episodes}


PLOT_TITLES = {"unit_costs": "Human vs robot unit cost", "episode_distributions": "Per-episode distributions",
               "training_curve": "Training curve"}


def render_markdown(doc: Mapping[str, Any], plot_files: Mapping[str, str] | None = None) -> str:
    """The Markdown report; ``plot_files`` maps plot name -> relative image path."""
    s = _sections(doc)
    parts = [f"# Task pricing report: {md_escape(doc['task']['task_id'])}", "", f"**{md_escape(headline(doc))}**", "",
             _md_table(("", ""), [(k, v) for k, v in s["facts"]]), "",
             f"## Pricing (spread share {fmt(doc['pricing']['spread_share'])})", "",
             "`aggregate` pools all evaluation episodes; mean and p10/p50/p90 are over episodes.", "",
             _md_table(("metric", *STAT_COLUMNS, "unit"), table_rows(doc)), "",
             "## Inputs", "", _md_table(("parameter", "value", "unit", "source"), s["inputs"]), ""]
    for name, path in (plot_files or {}).items():
        parts += [f"## {PLOT_TITLES.get(name, name)}", "", f"![{name}]({path})", ""]
    parts += ["## Evaluation episodes", "", _md_table(s["ep_keys"], s["episodes"]), "",
              f"_Document schema {doc['schema']} v{doc['schema_version']}._", ""]
    return "\n".join(parts)


_CSS = """body{font-family:system-ui,-apple-system,Segoe UI,Helvetica,Arial,sans-serif;margin:2rem auto;
max-width:1100px;color:#222;padding:0 1rem}h1{margin-bottom:.2rem}h2{border-bottom:1px solid #ddd;
padding-bottom:.2rem;margin-top:2rem}.headline{font-size:1.15rem;background:#eef6ee;border-left:4px solid #2ca02c;
padding:.7rem 1rem}.bad{background:#fbeeee;border-color:#d62728}table{border-collapse:collapse;margin:.5rem 0;
font-size:.92rem}td,th{border:1px solid #ddd;padding:.3rem .6rem;text-align:left}th{background:#f5f5f5}
td.num{text-align:right;font-variant-numeric:tabular-nums}img{max-width:100%;margin:.5rem 0}
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
    agg = doc["pricing"]["aggregate"]
    bad = "" if agg.get("competitive") and (agg.get("implied_wage_usd_per_hour") or 0.0) >= 0 else " bad"
    body = [f"<h1>Task pricing report: {html.escape(doc['task']['task_id'])}</h1>",
            f'<p class="headline{bad}">{html.escape(headline(doc))}</p>',
            _html_table(None, s["facts"], "facts"),
            (f"<h2>Pricing <small>(spread share {fmt(doc['pricing']['spread_share'])}; aggregate pools all "
             "evaluation episodes, mean and p10/p50/p90 are over episodes)</small></h2>"),
            _html_table(("metric", *STAT_COLUMNS, "unit"), table_rows(doc), numeric_from=1)]
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
