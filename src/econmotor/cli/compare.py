"""``econmotor compare``: price several imported policies side by side and name the winner.

Every policy is evaluated by the same backend with the same request: the same seeds
(episode ``i`` seeded ``seed + REPORT_EVAL_SEED_OFFSET + i``), course, commanded speed and
datapack conditions. Each evaluation run is recorded and gets its usual report; then a
table and a plot (``compare.md``, ``compare.json``, ``compare.png`` in ``--output-dir``)
rank deployable policies by price per unit (lowest first) and the refused ones after them by their
fall-rate bound (lowest first), with units per hour, Wh per unit and the fall-rate bound, and say
whether the winner's price interval clears the runner-up's. The plot marks refused policies and draws
the acceptance limit on the fall-rate panel. Only a deployable policy can win: one that is not gets no
recommended price, so when none is deployable there is no winner.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import typer
from rich.console import Console
from rich.table import Table

from econmotor.cli._app import app, console, fits_unwrapped, make_backend, set_cpu_threads
from econmotor.cli.options import (
    EVAL_MAX_EPISODES_OPTION,
    EVAL_MAX_SECONDS_OPTION,
    SPREAD_SHARE_OPTION,
    TASK_ID_OPTION,
    TASKS_FILE_OPTION,
    check_imports_policies,
    course_speed_options,
    resolve_datapacks,
    resolve_objective,
    split_datapack_values,
)
from econmotor.cli.reporting import ReportInputs, price_imported
from econmotor.cli.validation import (
    check_command_speeds,
    check_db_url,
    check_flags,
    check_output_dir,
    evaluation_plan,
)
from econmotor.config.acceptance import ERROR_RATE_CHECK
from econmotor.economics.pricing import PricingPolicy
from econmotor.economics.sequential_rule import SequentialPlan
from econmotor.errors import ConfigError
from econmotor.motor_backend.factory import backend_class, load_checked_catalog
from econmotor.motor_backend.results import PROVENANCE_KEY
from econmotor.motor_backend.run_dir import REPORT_EVAL_SEED_OFFSET
from econmotor.report.text import fmt

#: intervals narrower than this fraction of the price cannot tell policies apart: the episodes barely
#: differ (nominal conditions vary only the start pose), which is not evidence of how a difference holds
NO_WIDTH_REL = 1e-3
COLUMNS = ("policy", "price USD/unit", "90% interval", "units/h", "Wh/unit", "falls", "fall-rate bound",
           "speed m/s", "mech / elec W", "verdict")


def fall_rate_bound(doc: dict[str, Any]) -> float | None:
    """The upper bound of the error (fall) rate the report's verdict judged (a sequential evaluation's
    confidence sequence); a report without that check: its interval's upper end."""
    for check in (doc.get("verdict") or {}).get("checks") or []:
        if check.get("name") == ERROR_RATE_CHECK and check.get("bound") is not None:
            return float(check["bound"])
    return ((doc["uncertainty"]["intervals"].get("error_rate")) or {}).get("high")


def comparison_row(policy_id: str, doc: dict[str, Any]) -> dict[str, Any]:
    """One policy's ranking figures from its report document."""
    agg = doc["pricing"]["aggregate"]
    intervals = doc["uncertainty"]["intervals"]
    price_iv = intervals.get("price_usd_per_unit") or {}
    provenance = ((doc["runs"]["eval"] or {}).get("config") or {}).get(PROVENANCE_KEY) or {}  # MotorEvalResult's
    return {"policy": policy_id, "price_usd_per_unit": agg.get("price_usd_per_unit"),
            "price_low": price_iv.get("low"), "price_high": price_iv.get("high"),
            # what its report says to charge (the cautious end of the intervals; None: not deployable)
            "charge_usd_per_unit": (doc.get("recommendation") or {}).get("price_usd_per_unit"),
            "units_per_hour": agg.get("mpl_units_per_hour"), "wh_per_unit": doc["metrics"]["econ"].get(
                "energy_wh_per_unit"), "fall_rate_bound": fall_rate_bound(doc),
            "commanded_speed_m_per_s": provenance.get("commanded_speed_m_per_s"),
            "achieved_speed_m_per_s": provenance.get("achieved_speed_m_per_s"),
            "falls": doc["metrics"]["raw"].get("errors"),
            "units_attempted": doc["metrics"]["raw"].get("units_attempted"),
            "mean_mech_power_w": provenance.get("mean_mech_power_w"), "mean_power_w": provenance.get("mean_power_w"),
            "verdict": doc["verdict"]["label"], "deployable": doc["verdict"]["deployable"],
            "report_id": doc["registry"]["report_id"]}


def rank(rows: list[dict[str, Any]]) -> tuple[list[dict[str, Any]], str]:
    """Rows in rank order and the verdict in words.

    Deployable policies rank first, by price per unit (lowest first; a policy without a finite price last). The
    others follow by their fall-rate upper bound (lowest first; without one last), never by a price: they are
    refused one, so their prices are diagnostics. Only a deployable policy can win, so with none deployable there
    is no winner."""
    def key(r: dict[str, Any]) -> tuple[bool, float, float]:
        figure = r["price_usd_per_unit"] if r["deployable"] else r["fall_rate_bound"]
        return (not r["deployable"], figure if figure is not None else float("inf"), -(r["units_per_hour"] or 0.0))

    ranked = sorted(rows, key=key)
    eligible = [r for r in ranked if r["deployable"]]
    if not eligible:
        return ranked, (f"no winner: none of the {len(ranked)} policies is deployable (see the verdicts); "
                        "a not-deployable policy gets no recommended price")
    best = eligible[0]
    winner = (f"winner: {best['policy']}, charging {fmt(best['charge_usd_per_unit'])} USD/unit (its report's "
              f"price; point estimate {fmt(best['price_usd_per_unit'])})")
    if len(eligible) == 1:
        return ranked, (f"{winner}; the only deployable one of the {len(ranked)} policies (the others get no "
                        "recommended price)")
    second = eligible[1]
    if all(r["price_low"] is not None and r["price_high"] - r["price_low"] <= NO_WIDTH_REL * abs(r["price_high"])
           for r in (best, second)):
        clear = (f"both intervals are narrower than {NO_WIDTH_REL:.1%} of the price: the episodes barely differ "
                 "(nominal conditions vary only the start pose), so they cannot tell whether the difference would "
                 "hold; compare under a datapack that varies the conditions")
    elif (best["price_high"] is not None and second["price_low"] is not None
          and best["price_high"] < second["price_low"]):
        clear = (f"the difference is larger than the intervals ({best['policy']}'s 90% interval ends at "
                 f"{fmt(best['price_high'])} USD/unit, below {second['policy']}'s, which starts at "
                 f"{fmt(second['price_low'])})")
    else:
        clear = (f"the difference is NOT larger than the intervals ({best['policy']}: "
                 f"{fmt(best['price_low'])} - {fmt(best['price_high'])}; {second['policy']}: "
                 f"{fmt(second['price_low'])} - {fmt(second['price_high'])} USD/unit)")
    excluded = [r["policy"] for r in ranked if not r["deployable"]]
    if excluded:
        clear += f"; not deployable, so not in the running: {', '.join(excluded)}"
    return ranked, f"{winner}; {clear}"


def _cells(r: dict[str, Any]) -> tuple[str, ...]:
    speed = f"{fmt(r['achieved_speed_m_per_s'])} / {fmt(r['commanded_speed_m_per_s'])}"
    power = f"{fmt(r['mean_mech_power_w'])} / {fmt(r['mean_power_w'])}"
    return (r["policy"], fmt(r["price_usd_per_unit"]), f"{fmt(r['price_low'])} - {fmt(r['price_high'])}",
            fmt(r["units_per_hour"]), fmt(r["wh_per_unit"]), fmt(r["falls"]), fmt(r["fall_rate_bound"]), speed, power,
            r["verdict"])


def comparison_table(ranked: list[dict[str, Any]], title: str, out: Console) -> Table:
    """The console table: one row per policy where that fits ``out``'s width uncut and unwrapped,
    else one row per figure with a column per policy (in rank order). Cells fold, never cut: ids are copied."""
    cells = [_cells(r) for r in ranked]
    table = Table(title=title)
    for column in COLUMNS:
        table.add_column(column, justify="left" if column in ("policy", "verdict") else "right", overflow="fold")
    for row in cells:
        table.add_row(*row)
    if fits_unwrapped(table, out):
        return table
    table = Table(title=title)
    table.add_column(COLUMNS[0], overflow="fold")
    for row in cells:
        table.add_column(row[0], justify="right", overflow="fold")
    for i, figure in enumerate(COLUMNS[1:], start=1):
        table.add_row(figure, *(row[i] for row in cells))
    return table


def write_comparison(ranked: list[dict[str, Any]], summary: str, out_dir: Path, context: dict[str, Any]) -> list[Path]:
    """``compare.json``, ``compare.md`` and ``compare.png`` (:func:`comparison_figure`)."""
    out_dir.mkdir(parents=True, exist_ok=True)
    (out_dir / "compare.json").write_text(json.dumps({"context": context, "ranking": ranked, "summary": summary},
                                                     indent=2, default=str), encoding="utf-8")
    lines = [f"# Comparison: {context['task_id']}", "", f"{summary}.", "",
             f"Same seeds ({context['seeds']}), course, commanded speed and conditions "
             f"(datapacks: {', '.join(context['datapacks']) or 'none'}); speed: achieved / commanded while walking.",
             "", "| " + " | ".join(COLUMNS) + " |", "|" + "---|" * len(COLUMNS)]
    lines += ["| " + " | ".join(_cells(r)) + " |" for r in ranked]
    (out_dir / "compare.md").write_text("\n".join(lines) + "\n", encoding="utf-8")
    comparison_figure(ranked, context.get("fall_rate_limit")).savefig(out_dir / "compare.png", dpi=100)
    return [out_dir / "compare.json", out_dir / "compare.md", out_dir / "compare.png"]


#: how a refused (not deployable) policy's bars look in ``compare.png``
REFUSED_BAR = {"facecolor": "lightgrey", "edgecolor": "dimgray", "hatch": "//"}
PANELS = (("price_usd_per_unit", "price per unit (USD)"), ("units_per_hour", "units per hour"),
          ("wh_per_unit", "Wh per unit"), ("fall_rate_bound", "fall-rate bound (95%)"))


#: the longest policy name a bar is labelled with; longer ones (paths) get a letter and a line in the key
MAX_TICK_LABEL = 16


def policy_labels(policies: list[str]) -> tuple[list[str], list[str]]:
    """Short, distinct bar labels of ``policies``, and the key that names them (empty when the labels are the names).

    A shipped name loses its backend prefix and a file its folder and suffix (``holosoma:g1_29dof/ppo`` ->
    ``g1_29dof/ppo``, ``exports/v3.onnx`` -> ``v3``); when one of those is longer than :data:`MAX_TICK_LABEL`
    characters or two are the same (every run's file is ``policy.onnx``), the bars are lettered A, B, ... and the
    key gives each letter's policy as the user named it: four paths as ticks ran into each other."""
    short = [p.split(":", 1)[-1] if p.startswith("holosoma:") else Path(p).stem for p in policies]
    if len(set(short)) == len(short) and max(map(len, short), default=0) <= MAX_TICK_LABEL:
        return short, []
    letters = [chr(ord("A") + i) if i < 26 else f"P{i + 1}" for i in range(len(policies))]
    return letters, [f"{letter}: {policy}" for letter, policy in zip(letters, policies, strict=True)]


def comparison_figure(ranked: list[dict[str, Any]], fall_rate_limit: float | None = None) -> Any:
    """The comparison plot (a matplotlib Figure): price per unit with its interval, units/h, Wh/unit and the
    fall-rate bound per policy, in rank order, each bar labelled by :func:`policy_labels` (a key under the panels
    where they are letters). A refused (not deployable) policy's bars are grey and hatched and its price is
    labelled "refused"; the fall-rate panel draws the acceptance limit ``fall_rate_limit``."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    names, legend = policy_labels([r["policy"] for r in ranked])
    key_in = 0.18 * len(legend)  # inches of key lines under the panels
    fig = Figure(figsize=(12, 3.2 + key_in))
    FigureCanvasAgg(fig)
    for i, (key, label) in enumerate(PANELS):
        ax = fig.add_subplot(1, 4, i + 1)
        values = [r[key] if r[key] is not None else 0.0 for r in ranked]
        bars = ax.bar(names, values, color="tab:blue" if key == "price_usd_per_unit" else "tab:gray",
                      **({"yerr": _price_errors(ranked, values), "capsize": 4} if key == "price_usd_per_unit" else {}))
        for bar, row in zip(bars, ranked, strict=True):
            if not row["deployable"]:
                bar.set(**REFUSED_BAR)
                if key == "price_usd_per_unit":  # a price it may not charge; the label above its interval
                    top = max(bar.get_height(), row["price_high"] or 0.0)
                    ax.annotate("refused", (bar.get_x() + bar.get_width() / 2, top), ha="center", va="bottom",
                                fontsize=7, color="dimgray", xytext=(0, 4), textcoords="offset points")
        if key == "price_usd_per_unit" and not all(r["deployable"] for r in ranked):
            ax.set_ylim(top=ax.get_ylim()[1] * 1.12)  # room for the "refused" labels
        if key == "fall_rate_bound" and fall_rate_limit is not None:
            text = f"acceptance limit {fmt(fall_rate_limit)}"
            ax.axhline(fall_rate_limit, color="tab:red", linestyle="--", linewidth=1, label=text)
            ax.annotate(text, (1.0, fall_rate_limit), xycoords=("axes fraction", "data"), ha="right", va="bottom",
                        fontsize=7, color="tab:red", xytext=(-2, 2), textcoords="offset points",
                        bbox={"facecolor": "white", "edgecolor": "none", "pad": 1})
        ax.set_title(label, fontsize=9)
        ax.tick_params(axis="x", labelsize=7)
    if legend:
        fig.text(0.01, 0.01, "\n".join(legend), fontsize=8, va="bottom", ha="left", family="monospace")
    fig.tight_layout(rect=(0, key_in / (3.2 + key_in), 1, 1))
    return fig


def _price_errors(ranked: list[dict[str, Any]], values: list[float]) -> list[list[float]]:
    """Error bars of the price panel: each 90% interval around its point (none where it is unknown)."""
    lows = [r["price_low"] if r["price_low"] is not None else v for v, r in zip(values, ranked, strict=True)]
    highs = [r["price_high"] if r["price_high"] is not None else v for v, r in zip(values, ranked, strict=True)]
    return [[max(v - lo, 0.0) for v, lo in zip(values, lows, strict=True)],
            [max(hi - v, 0.0) for v, hi in zip(values, highs, strict=True)]]


def check_policies(policies: list[str]) -> None:
    """At least two policies, none named twice."""
    if len(policies) < 2:
        raise ConfigError("--policy", None, f"compare needs at least two policies, got {len(policies)}")
    if len(set(policies)) != len(policies):
        raise ConfigError("--policy", None, f"a policy is named twice: {policies}")


def price_each(inputs: ReportInputs, backend: Any, policies: list[str], eval_episodes: int, seed: int,
               plan: SequentialPlan | None) -> tuple[list[dict[str, Any]], list[int]]:
    """Each policy evaluated with the same request, recorded and reported: its ranking row and episode count."""
    for policy_id in policies:  # bad input records nothing
        backend.check_policy(policy_id)
    rows, counts = [], []
    for policy_id in policies:
        outcome = price_imported(inputs, backend, policy_id, eval_episodes, seed, f"econmotor compare: {policy_id}",
                                 None, plan)
        rows.append(comparison_row(policy_id, outcome.document))
        counts.append(outcome.document["uncertainty"]["evidence"]["episodes"])
    return rows, counts


def show_comparison(ranked: list[dict[str, Any]], summary: str, files: list[Path], title: str) -> None:
    """The table, the verdict and where the files are."""
    console.print(comparison_table(ranked, title, console))
    console.print(summary, highlight=False, soft_wrap=True)
    for path in files:
        console.print(f"{path.suffix[1:]:>8}: {path}", highlight=False, soft_wrap=True)


POLICIES = typer.Option(..., "--policy", help="A policy to price (repeat, at least two): an ONNX file or a shipped "
                        "name such as holosoma:g1_29dof/ppo.")
MOTOR_BACKEND = typer.Option("holosoma", "--motor-backend", help="A backend that imports policies.")
EVAL_EPISODES = typer.Option(None, "--eval-episodes", help="Exactly N episodes per policy (default: a sequential "
                             "evaluation of each, until its verdict is decided, or a cap).")
SEED = typer.Option(0, "--seed", help="Seed of the evaluations (the same for every policy).")
DATAPACKS = typer.Option([], "--datapacks", help="Datapack YAML paths or registered ids (stress).")
COMMAND_SPEED = typer.Option(None, "--command-speed", help="Commanded walking speed, m/s (default: the task "
                             "catalog's course speed; at most 10 m/s and each policy's own command range).")
OUTPUT_DIR = typer.Option(None, "--output-dir", help="Where reports and the comparison go (default "
                          "reports/<task>/compare).")
DB_URL = typer.Option(None, "--db-url", help="Registry URL (default as for `econmotor report`).")


@app.command("compare")
def compare_command(
    task_id: str = TASK_ID_OPTION,
    policies: list[str] = POLICIES,
    motor_backend: str = MOTOR_BACKEND,
    eval_episodes: int = EVAL_EPISODES,
    eval_max_episodes: int = EVAL_MAX_EPISODES_OPTION,
    eval_max_seconds: float = EVAL_MAX_SECONDS_OPTION,
    seed: int = SEED,
    datapacks: list[str] = DATAPACKS,
    command_speed: float = COMMAND_SPEED,
    output_dir: Path = OUTPUT_DIR,
    db_url: str = DB_URL,
    tasks_file: list[Path] = TASKS_FILE_OPTION,
    spread_share: float = SPREAD_SHARE_OPTION,
) -> None:
    """Price several imported policies on the same seeds, course and conditions; rank them and name the winner."""
    check_flags(eval_episodes=eval_episodes, seed=seed, spread_share=spread_share,
                eval_max_episodes=eval_max_episodes, eval_max_seconds=eval_max_seconds)
    check_policies(policies)
    check_command_speeds([command_speed], policies)
    cls = backend_class(motor_backend)  # resolved once; the checks below ask it
    check_imports_policies(cls, "--motor-backend")
    speed = course_speed_options(cls, command_speed)  # the contract's keyword, where declared
    url = check_db_url(db_url, create=True)
    catalog = load_checked_catalog(tasks_file)
    task = catalog.get(task_id)
    task.backend_entry(motor_backend)
    packs = resolve_datapacks(split_datapack_values(datapacks), url)
    out_dir = check_output_dir("--output-dir", output_dir or Path("reports") / task_id / "compare")
    inputs = ReportInputs(task, catalog, url, resolve_objective(None), packs, out_dir, PricingPolicy(spread_share),
                          backend_cls=cls)
    set_cpu_threads()
    backend = make_backend(motor_backend, tasks_file, catalog=catalog, **speed)
    plan = evaluation_plan(backend, task_id, eval_episodes, eval_max_episodes, eval_max_seconds)
    rows, counts = price_each(inputs, backend, policies, eval_episodes or 0, seed, plan)
    ranked, summary = rank(rows)
    first = seed + REPORT_EVAL_SEED_OFFSET
    seeds = f"{first}-{first + max(counts) - 1}"
    files = write_comparison(ranked, summary, out_dir, {"task_id": task_id, "seeds": seeds,
                                                         "datapacks": [p.id for p in packs],
                                                         "commanded_speed_m_per_s": command_speed,
                                                         "fall_rate_limit": task.acceptance.max_error_rate})
    each = f"{eval_episodes} episodes each" if eval_episodes else \
        f"sequential evaluations ({', '.join(map(str, counts))} episodes, until each verdict was decided)"
    show_comparison(ranked, summary, files, f"{task_id}: {len(ranked)} policies, {each}, seeds {seeds}")
