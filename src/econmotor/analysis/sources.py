"""Episode tables from the run registry.

``episodes_from_registry`` reads the per-episode summaries of completed runs
(filters: task, backend, datapacks, objective name, run kind) and adds what the
solver needs from the run: datapacks, seed, the sweep cell key and commanded speed stored
in the run's config (else the speed the episodes walked at, where they record one), and
the task's electricity price from the task catalog (read only by objectives that price
energy, ``energy_term: usd``; ``r_energy`` is ``-Wh`` otherwise).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from econmotor.analysis.episode_table import EpisodeTable
from econmotor.errors import ConfigError, UnknownNameError
from econmotor.tasks import load_catalog


def task_energy_prices(task_ids: Sequence[str], task_files: Sequence[str] = ()) -> dict[str, float | None]:
    """Task id -> electricity price USD/kWh from the catalog (``None`` for unknown tasks)."""
    catalog = load_catalog(task_files)
    out: dict[str, float | None] = {}
    for task_id in task_ids:
        try:
            out[task_id] = catalog.get(task_id).economics.energy_price_usd_per_kwh
        except UnknownNameError:
            out[task_id] = None
    return out


def episodes_from_registry(registry: Any, *, task_id: str | None = None, backend: str | None = None,
                           datapacks: Sequence[str] | None = None, objective: str | None = None,
                           kind: str | None = None, task_files: Sequence[str] = ()) -> EpisodeTable:
    """Episodes of the completed runs matching every given filter, as an :class:`EpisodeTable`.

    Args:
        registry: an ``econmotor.store.Registry``.
        task_id, backend, objective, kind: exact matches on the run (objective = its name).
        datapacks: keep runs that used every listed datapack id.
        task_files: extra task catalog files (for the electricity price of user tasks).
    """
    filters = {"task_id": task_id, "backend": backend, "datapacks": datapacks, "objective": objective,
               "kind": kind}
    episodes = registry.episodes(**filters, status="completed")
    if not episodes:
        given = ", ".join(f"{k}={v}" for k, v in filters.items() if v) or "none"
        raise ConfigError(registry.display_url, None,
                          f"no episodes of completed runs match the filters ({given}); "
                          "record runs with `econmotor sweep` or `econmotor report`, or relax the filters")
    runs = {r.id: r for r in registry.runs(task_id=task_id, backend=backend, datapacks=datapacks,
                                           objective=objective, kind=kind, status="completed")}
    prices = task_energy_prices(sorted({ep.task_id for ep in episodes}), task_files)
    records = []
    for ep in episodes:
        config = runs[ep.run_id].config if ep.run_id in runs else {}
        records.append({**ep.summary, "run_id": str(ep.run_id), "task_id": ep.task_id, "backend": ep.backend,
                        "objective": ep.objective_name, "datapacks": list(ep.datapack_ids), "seed": ep.seed,
                        "cell_key": config.get("cell_key"), "termination_reason": ep.termination_reason,
                        "commanded_speed_m_per_s": config.get("commanded_speed_m_per_s",
                                                              ep.summary.get("commanded_speed_m_per_s")),
                        "energy_price_usd_per_kwh": prices[ep.task_id]})
    return EpisodeTable.from_records(records, registry.display_url)
