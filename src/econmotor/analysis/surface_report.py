"""Render an objective surface: a JSON document, a Markdown table and 2-D plots of the front.

The JSON document (``format: econmotor-objective-surface/1``) holds the runs with their
mean metrics and per-set validity, one cell per (objective, constraint set) and the
Pareto front. A cell whose set no run meets says so in ``note`` and names the
run of highest penalised utility under ``fallback_run_id``. ``choices`` gives each named
objective's choice with its mean J and margin over the runner-up (90% intervals) and, where
the runs walk a commanded speed, ``operating_points`` each run's pooled figures with intervals
(:mod:`econmotor.analysis.operating_point`).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from itertools import combinations
from pathlib import Path
from typing import Any

import numpy as np

from econmotor.analysis.episode_table import finite_or_none
from econmotor.analysis.objective_surface import ObjectiveSurface
from econmotor.analysis.operating_point import Choice, OperatingPoint
from econmotor.analysis.pareto import PARETO_CRITERIA, ParetoFront, pareto_front

SURFACE_FORMAT = "econmotor-objective-surface/1"
_LABELS = {"mpl_units_per_hour": "MPL (units/h)", "energy_wh_per_unit": "energy (Wh/unit)",
           "error_rate": "error rate", "risk_score": "risk score"}


@dataclass(frozen=True)
class SurfaceCell:
    """The answer for one (objective, constraint set)."""

    objective: str
    constraint_set: str
    valid: bool
    best_run_id: str | None
    datapacks: tuple[str, ...]
    utility: float | None
    valid_fraction: float | None
    runs_valid: int
    fallback_run_id: str
    note: str

    def to_dict(self) -> dict[str, Any]:
        return {"objective": self.objective, "constraint_set": self.constraint_set, "valid": self.valid,
                "best_run_id": self.best_run_id, "datapacks": list(self.datapacks),
                "utility": self.utility, "valid_fraction": self.valid_fraction, "runs_valid": self.runs_valid,
                "fallback_run_id": self.fallback_run_id, "note": self.note}


def surface_cells(surface: ObjectiveSurface) -> list[SurfaceCell]:
    """One :class:`SurfaceCell` per (objective, constraint set), objectives outermost."""
    runs = surface.table.runs
    best_util = surface.best_utility()
    cells = []
    for k, objective in enumerate(surface.objectives):
        for c, cset in enumerate(surface.constraint_sets):
            best, n_valid = int(surface.best_run[k, c]), int(surface.valid[:, c].sum())
            fallback = runs[int(surface.fallback_run[k, c])]
            if best >= 0:
                run = runs[best]
                note = f"best of {n_valid} valid run(s)"
                cells.append(SurfaceCell(objective.name, cset.name, True, run.run_id, run.datapacks,
                                         finite_or_none(best_util[k, c]),
                                         float(surface.valid_fraction[best, c]), n_valid, fallback.run_id, note))
            else:
                note = (f"no run meets constraint set '{cset.name}'; least violating under this objective: "
                        f"run {fallback.run_id} (penalised utility)")
                cells.append(SurfaceCell(objective.name, cset.name, False, None, (), None, None, 0,
                                         fallback.run_id, note))
    return cells


def front_values(surface: ObjectiveSurface) -> np.ndarray:
    """(R, 4) run means on the Pareto criteria, in :data:`PARETO_CRITERIA` order."""
    return np.column_stack([surface.run_metrics[c] for c in PARETO_CRITERIA])


def surface_document(surface: ObjectiveSurface, front: ParetoFront | None = None,
                     inputs: dict[str, Any] | None = None, chosen: list[Choice] | None = None,
                     points: list[OperatingPoint] | None = None) -> dict[str, Any]:
    """The JSON document (see module docstring); non-finite numbers become null."""
    front = front or pareto_front(front_values(surface))
    runs = []
    for r, run in enumerate(surface.table.runs):
        runs.append({**run.to_dict(), "episodes": int(surface.table.episode_counts()[r]),
                     "metrics": {k: finite_or_none(v[r]) for k, v in surface.run_metrics.items()},
                     "utility": {o.name: finite_or_none(surface.utility[r, k])
                                 for k, o in enumerate(surface.objectives)},
                     "valid": {s.name: bool(surface.valid[r, c]) for c, s in enumerate(surface.constraint_sets)},
                     "valid_fraction": {s.name: float(surface.valid_fraction[r, c])
                                        for c, s in enumerate(surface.constraint_sets)},
                     "on_pareto_front": r in front.indices})
    unmet = [s.name for c, s in enumerate(surface.constraint_sets) if not surface.valid[:, c].any()]
    return {
        "format": SURFACE_FORMAT,
        "inputs": inputs or {},
        "utility": "mean episodic J = sum_i w_i * r_i over [r_mpl, r_error, r_energy, r_safety, r_novelty]",
        "validity": "constraints checked on each run's mean; valid_fraction = share of its episodes meeting them",
        "num_episodes": surface.table.num_episodes,
        "objectives": [o.to_dict() for o in surface.objectives],
        "constraint_sets": [s.to_dict() for s in surface.constraint_sets],
        "constraint_sets_no_run_meets": unmet,
        "cells": [cell.to_dict() for cell in surface_cells(surface)],
        "pareto_front": {**front.to_dict(), "run_ids": [surface.table.runs[i].run_id for i in front.indices]},
        "runs": runs,
        "choices": _finite([c.to_dict() for c in chosen or []]),
        "operating_points": _finite([p.to_dict() for p in points or []]),
    }


def _finite(value: Any) -> Any:
    """``value`` with every non-finite float made null (JSON has no inf/NaN)."""
    if isinstance(value, dict):
        return {k: _finite(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_finite(v) for v in value]
    return finite_or_none(value) if isinstance(value, float) else value


def _fmt(value: float | None, spec: str = ".3g") -> str:
    return "—" if value is None else format(value, spec)


def surface_markdown(document: dict[str, Any]) -> str:
    """A Markdown report of the document: the cell table, the unmet sets and the Pareto front."""
    lines = ["# Objective surface", "",
             (f"{document['num_episodes']} episodes from {len(document['runs'])} runs; "
             f"{len(document['objectives'])} objectives x {len(document['constraint_sets'])} constraint sets."),
             "", ("| objective | constraint set | valid | best run | datapacks | utility J | "
             "episodes meeting set | valid runs |"), "|---|---|---|---|---|---|---|---|"]
    for cell in document["cells"]:
        frac = None if cell["valid_fraction"] is None else 100 * cell["valid_fraction"]
        lines.append(f"| {cell['objective']} | {cell['constraint_set']} | {'yes' if cell['valid'] else 'NO'} | "
                     f"{cell['best_run_id'] or '—'} | {', '.join(cell['datapacks']) or '—'} | "
                     f"{_fmt(cell['utility'], '.4g')} | {_fmt(frac, '.0f')}{'%' if frac is not None else ''} | "
                     f"{cell['runs_valid']} |")
    for name in document["constraint_sets_no_run_meets"]:
        lines += ["", f"**No run meets constraint set `{name}`.**"]
    front = document["pareto_front"]
    ref = ", ".join(f"{k} {v:.4g}" for k, v in front["reference_point"].items())
    lines += ["", "## Pareto front (MPL up, energy per unit down, error rate down, risk down)", "",
              (f"{len(front['run_ids'])} non-dominated run(s); hypervolume {front['hypervolume']:.6g} "
              f"against the reference point ({ref}); {front['hypervolume_method']}."), "",
              "| run | datapacks | MPL units/h | Wh/unit | error rate | risk |", "|---|---|---|---|---|---|"]
    by_id = {r["run_id"]: r for r in document["runs"]}
    for run_id in front["run_ids"]:
        run, m = by_id[run_id], by_id[run_id]["metrics"]
        lines.append(f"| {run_id} | {', '.join(run['datapacks'])} | {_fmt(m['mpl_units_per_hour'])} | "
                     f"{_fmt(m['energy_wh_per_unit'])} | {_fmt(m['error_rate'])} | {_fmt(m['risk_score'])} |")
    return "\n".join(lines + _choice_lines(document) + _operating_lines(document)) + "\n"


def interval_text(iv: dict[str, Any] | None, spec: str = ".3g") -> str:
    """``point [low, high]`` of an interval's dict (``—`` for a missing number)."""
    if iv is None:
        return "—"
    return f"{_fmt(iv['point'], spec)} [{_fmt(iv['low'], spec)}, {_fmt(iv['high'], spec)}]"


def _choice_lines(document: dict[str, Any]) -> list[str]:
    if not document["choices"]:
        return []
    lines = ["", "## Choices (mean J and margin over the runner-up, 90% intervals)", "",
             "| objective | constraint set | run | speed m/s | J | runner-up | margin | separated |",
             "|---|---|---|---|---|---|---|---|"]
    for c in document["choices"]:
        lines.append(f"| {c['objective']} | {c['constraint_set']} | {c['run_id']} | "
                     f"{_fmt(c['commanded_speed_m_per_s'], 'g')} | {interval_text(c['utility'], '.4g')} | "
                     f"{c['runner_up_run_id'] or '—'} | {interval_text(c['margin'], '.3g')} | "
                     f"{'yes' if c['separated'] else 'no'} |")
    return lines


def _operating_lines(document: dict[str, Any]) -> list[str]:
    if not document["operating_points"]:
        return []
    lines = ["", "## Operating points (pooled over each run's episodes, 90% intervals)", "",
             "| run | speed m/s | episodes | units/h | Wh/unit | units/charge | errors / attempted | "
             "error-rate bound | price USD/unit | damage USD/unit |", "|---|---|---|---|---|---|---|---|---|---|"]
    for p in document["operating_points"]:
        f, ev = p["figures"], p["evidence"]
        lines.append(f"| {p['run_id']} | {_fmt(p['commanded_speed_m_per_s'], 'g')} | {ev['episodes']} | "
                     f"{interval_text(f['mpl_units_per_hour'])} | {interval_text(f['energy_wh_per_unit'])} | "
                     f"{interval_text(f.get('battery_units_per_charge'))} | {_fmt(ev['errors'], 'g')} / "
                     f"{_fmt(ev['units_attempted'], '.3g')} | {_fmt(f['error_rate']['high'], '.3g')} | "
                     f"{interval_text(f['price_usd_per_unit'])} | {interval_text(f['damage_usd_per_unit'])} |")
    return lines


def plot_front(surface: ObjectiveSurface, front: ParetoFront, path: str | Path) -> Path:
    """2-D projections of the runs (front highlighted) with each preset's unconstrained choice marked."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    values = front_values(surface)
    on_front = np.zeros(len(values), bool)
    on_front[list(front.indices)] = True
    presets = [(k, o) for k, o in enumerate(surface.objectives) if o.kind == "preset"]
    choices = {o.name: int(np.argmax(surface.utility[:, k])) for k, o in presets}
    pairs = list(combinations(range(len(PARETO_CRITERIA)), 2))
    fig, axes = plt.subplots(2, 3, figsize=(15, 9))
    names = list(PARETO_CRITERIA)
    markers = "o^sDvP*Xh"
    for ax, (a, b) in zip(axes.ravel(), pairs, strict=True):
        finite = np.isfinite(values[:, a]) & np.isfinite(values[:, b])
        ax.scatter(values[finite & ~on_front, a], values[finite & ~on_front, b], c="lightgray", s=18,
                   label="dominated run")
        ax.scatter(values[finite & on_front, a], values[finite & on_front, b], c="tab:blue", s=30,
                   label="Pareto front")
        for i, (name, r) in enumerate(choices.items()):
            if finite[r]:
                ax.scatter(values[r, a], values[r, b], marker=markers[i % len(markers)], s=120,
                           facecolors="none", edgecolors=f"C{i + 1}", linewidths=2, label=f"{name} choice")
        ax.set_xlabel(_LABELS[names[a]])
        ax.set_ylabel(_LABELS[names[b]])
        ax.grid(alpha=0.3)
    handles, labels = axes.ravel()[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="lower center", ncol=min(len(labels), 5), frameon=False)
    fig.suptitle(f"Pareto front of {len(values)} runs: hypervolume {front.hypervolume:.4g} "
                 "(preset choices: highest mean J, unconstrained)")
    fig.tight_layout(rect=(0, 0.06, 1, 0.96))
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.stem + ".tmp" + path.suffix)
    fig.savefig(tmp, dpi=110)
    plt.close(fig)
    tmp.replace(path)
    return path


def write_surface_outputs(surface: ObjectiveSurface, output_dir: str | Path,
                          reference_point: dict[str, float] | None = None,
                          inputs: dict[str, Any] | None = None, chosen: list[Choice] | None = None,
                          points: list[OperatingPoint] | None = None) -> dict[str, Path]:
    """Write ``objective_surface.json``, ``objective_surface.md`` and ``pareto_front.png`` atomically;
    ``chosen`` and ``points`` (:mod:`econmotor.analysis.operating_point`) go into both documents."""
    out = Path(output_dir)
    out.mkdir(parents=True, exist_ok=True)
    front = pareto_front(front_values(surface), reference_point)
    document = surface_document(surface, front, inputs, chosen, points)
    files = {"json": out / "objective_surface.json", "markdown": out / "objective_surface.md"}
    for key, text in (("json", json.dumps(document, indent=2, allow_nan=False)),
                      ("markdown", surface_markdown(document))):
        tmp = files[key].with_suffix(files[key].suffix + ".tmp")
        tmp.write_text(text, encoding="utf-8")
        tmp.replace(files[key])
    files["plot"] = plot_front(surface, front, out / "pareto_front.png")
    return files
