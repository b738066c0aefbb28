"""Report plots as PNG bytes (matplotlib's object API on the Agg canvas: no display, no pyplot state).

Each function reads the report document (:mod:`econmotor.report.document`) and
returns PNG bytes, or ``None`` when there is nothing to draw:

- ``episode_distributions``: per-episode MPL (units/h), energy (Wh) and errors, on axes from
  zero; a quantity every episode agrees on is shown as its value, not as a histogram;
- ``training_curve``: mean episode return over training timesteps;
- ``unit_costs``: human unit cost vs the robot's unit cost and price (90% intervals) and,
  for a deployable robot, the recommended price.
"""

from __future__ import annotations

import io
import math
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from matplotlib.figure import Figure

_BLUE, _ORANGE, _GREEN, _GREY = "#1f77b4", "#ff7f0e", "#2ca02c", "#7f7f7f"


def _figure(width: float, height: float) -> Figure:
    """A figure on no display; matplotlib is imported here, not with the module (every CLI command imports
    the report renderer, and matplotlib takes most of a second to import)."""
    from matplotlib.figure import Figure

    return Figure(figsize=(width, height))


def _png(fig: Figure) -> bytes:
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    FigureCanvasAgg(fig)
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=100, bbox_inches="tight")
    return buf.getvalue()


def _finite(values: list[Any]) -> list[float]:
    return [float(v) for v in values if v is not None and math.isfinite(float(v))]


#: values whose spread is below this fraction of their size are one value shown as text, not a histogram.
SAME_VALUE_REL = 1e-3


def _draw_values(ax: Any, values: list[float], label: str, color: str) -> None:
    """A histogram on an axis that starts at zero, or the value itself when every episode agrees."""
    lo, hi = min(values), max(values)
    if hi - lo <= SAME_VALUE_REL * max(abs(hi), abs(lo), 1e-12):
        ax.text(0.5, 0.5, f"all {len(values)} episodes:\n{values[0]:.4g}", ha="center", va="center",
                transform=ax.transAxes, fontsize=12)
        ax.set_xticks([])
        ax.set_yticks([])
        ax.set_title(label, fontsize=9)
        return
    bins = min(20, max(3, len(set(values))))
    ax.hist(values, bins=bins, color=color, alpha=0.85, edgecolor="white")
    mean = sum(values) / len(values)
    ax.axvline(mean, color="black", linestyle="--", linewidth=1, label=f"mean {mean:.4g}")
    ax.legend(fontsize=8)
    if lo >= 0:  # honest axis: from zero, so the spread reads against the size of the value
        ax.set_xlim(0, hi * 1.05)
    ax.ticklabel_format(axis="x", useOffset=False, style="plain")
    ax.set_xlabel(label)
    ax.set_ylabel("episodes")


def episode_distributions(doc: dict[str, Any]) -> bytes | None:
    """Histograms of MPL, energy and errors per evaluation episode (a value where all episodes agree)."""
    episodes = doc.get("episodes") or []
    if not episodes:
        return None
    unit = doc["task"]["unit"]
    panels = [("mpl_units_per_hour", f"MPL ({unit} per hour)", _BLUE),
              ("energy_wh", "energy per episode (Wh)", _ORANGE),
              ("errors", "errors per episode", "#d62728")]
    fig = _figure(11, 3.2)
    for i, (key, label, color) in enumerate(panels):
        ax = fig.add_subplot(1, 3, i + 1)
        values = _finite([ep.get(key) for ep in episodes])
        if values:
            _draw_values(ax, values, label, color)
        else:
            ax.set_xlabel(label)
    fig.suptitle(f"{len(episodes)} evaluation episodes")
    fig.tight_layout()
    return _png(fig)


def training_curve(doc: dict[str, Any]) -> bytes | None:
    """Mean episode return against environment timesteps during training."""
    curve = [p for p in doc.get("training_curve") or [] if p.get("mean_return") is not None]
    if not curve:
        return None
    fig = _figure(7, 3.2)
    ax = fig.add_subplot(1, 1, 1)
    ax.plot([p["timesteps"] for p in curve], [p["mean_return"] for p in curve], marker="o", markersize=3,
            color=_BLUE)
    ax.set_xlabel("environment timesteps")
    ax.set_ylabel("mean episode return")
    ax.set_title("training curve")
    ax.grid(alpha=0.3)
    fig.tight_layout()
    return _png(fig)


def unit_costs(doc: dict[str, Any]) -> bytes | None:
    """Bars: human unit cost, robot unit cost and price with their 90% intervals (the recommended price
    only for a deployable robot)."""
    pricing = doc.get("pricing") or {}
    agg = pricing.get("aggregate") or {}
    intervals = (doc.get("uncertainty") or {}).get("intervals") or {}
    human = agg.get("human_unit_cost_usd")
    if human is None:
        return None
    bars = [("human", human, None, _GREY)]
    for key, label, color in (("robot_unit_cost_usd", "robot cost", _BLUE),
                              ("price_usd_per_unit", "price (point)", _GREEN)):
        iv = intervals.get(key) or {}
        band = (iv.get("low"), iv.get("high"))
        bars.append((label, agg.get(key), band if None not in band else None, color))
    rec = doc.get("recommendation")
    if rec:
        bars.append(("recommended", rec.get("price_usd_per_unit"), None, "#17becf"))
    fig = _figure(6.5, 3.4)
    ax = fig.add_subplot(1, 1, 1)
    drawn = [b for b in bars if b[1] is not None]
    for i, (_, value, band, color) in enumerate(drawn):
        ax.bar(i, value, color=color, width=0.6)
        if band is not None:
            ax.errorbar(i, value, yerr=[[max(value - band[0], 0)], [max(band[1] - value, 0)]], color="black",
                        capsize=6, linewidth=1)
        ax.text(i, value, f"{value:.3g}", ha="center", va="bottom", fontsize=9)
    missing = [b[0] for b in bars if b[1] is None]
    if missing:
        ax.text(0.98, 0.95, f"not finite: {', '.join(missing)} (robot completed no unit)", ha="right",
                va="top", transform=ax.transAxes, fontsize=8, color="#d62728")
    ax.set_xticks(range(len(drawn)), [b[0] for b in drawn])
    ax.set_ylim(0, max(max(b[1], (b[2] or (0, 0))[1] or 0) for b in drawn) * 1.15)
    ax.set_ylabel(f"USD per {doc['task']['unit']}")
    if (doc.get("verdict") or {}).get("deployable", True):
        ax.set_title("human vs robot unit cost (bars: 90% interval)")
    else:
        ax.set_title("NOT DEPLOYABLE: diagnostics, no recommended price\n(bars: 90% interval)", color="#d62728",
                     fontsize=10)
    fig.tight_layout()
    return _png(fig)


PLOTS: dict[str, Callable[[dict[str, Any]], bytes | None]] = {
    "unit_costs": unit_costs,
    "episode_distributions": episode_distributions,
    "training_curve": training_curve,
}


def render_plots(doc: dict[str, Any]) -> dict[str, bytes]:
    """Every plot that has data: name -> PNG bytes."""
    out = {}
    for name, make in PLOTS.items():
        png = make(doc)
        if png is not None:
            out[name] = png
    return out
