"""Render the report document as JSON, Markdown and self-contained HTML, and write the files atomically.

:func:`write_report` writes ``<name>.json``, ``<name>.md`` (with ``<name>_plots/*.png``
beside it) and ``<name>.html`` (plots embedded as base64 PNG, no external resources).
Every file is written to a temporary name in the same directory and renamed into
place, so a reader never sees half a report. The rows and sentences both documents share with
the console are :mod:`econmotor.report.text`.
"""

from __future__ import annotations

import base64
import html
import json
import os
import re
import tempfile
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from econmotor.report.plots import render_plots
from econmotor.report.text import (
    INTERVAL_COLUMN,
    STAT_COLUMNS,
    fmt,
    headline,
    imported_policy_text,
    learned_with_text,
    selection_text,
    started_from_text,
    table_rows,
    verdict_rows,
)

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
