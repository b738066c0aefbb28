"""EpisodeTable: recorded episodes as columns of numpy arrays, grouped by run.

The objective-surface solver never loops over episodes in Python: it reads the
columns below. A table is built once, at the edge, from episode summaries (the
dicts ``summarize_episodes`` returns, registry rows, or a JSONL export).

JSONL export format (``econmotor solve --export-jsonl``), one episode per line::

    {"format": "econmotor-episode/1",
     "run_id": "run-12", "task_id": "dishwashing", "backend": "dishwashing",
     "objective": "throughput", "datapacks": ["dw_base"], "seed": 0,
     "cell_key": "3f2a..." ,                   # sweep cell, or null
     "episode_index": 0,
     "mpl_units_per_hour": 48.0,               # good units / hour
     "error_rate": 0.04,                       # errors / attempted units
     "energy_wh": 12.5,                        # Wh in the episode
     "energy_wh_per_unit": 0.9,                # Wh per good unit; null = no good unit (infinite)
     "wage_parity": 0.71,                      # implied robot wage / human wage
     "catastrophic": false,                    # episode ended in a catastrophe
     "termination_reason": "max_steps",
     "novelty_score": 0.0, "risk_score": 0.0,
     "energy_price_usd_per_kwh": 0.12,         # USD/kWh, null = unknown; read only by
                                               # objectives that price energy (energy_term: usd)
     "commanded_speed_m_per_s": 0.8,           # the course's commanded speed, m/s; null = none
     "hours": 0.0333, "units_completed": 1.6,  # the counts pooled figures (ratios of sums) need,
     "units_attempted": 1.6, "errors": 0.0}    # h and units; null = unknown (optional)

Lines are self-contained (run fields repeat), so files concatenate. Reading
also accepts the summary names of ``econmotor.motor_backend.results.episode_summary``
(``mpl_episode``, ``error_rate_episode``, ``energy_Wh``, ``energy_Wh_per_unit``), and
the episode records of a shadow run (``shadow_episodes.jsonl``, format
:data:`SHADOW_EPISODE_FORMAT`): their ``econ`` summary is the episode, the run id is
the record's ``run_id`` or else the name of the run directory (the file's folder).
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from econmotor.errors import ConfigError
from econmotor.valuation.reward_builder import SUMMARY_ALIASES, is_catastrophic

EPISODE_FORMAT = "econmotor-episode/1"
#: the ``format`` of a shadow-mode episode record (``econmotor.rl.shadow``).
SHADOW_EPISODE_FORMAT = "econmotor-shadow-episode/1"
#: numeric episode columns (float64), in the order of :attr:`EpisodeTable.metric_matrix`.
METRIC_COLUMNS: tuple[str, ...] = (
    "mpl_units_per_hour", "error_rate", "energy_wh", "energy_wh_per_unit", "wage_parity",
    "novelty_score", "risk_score",
)
#: optional count columns (float64, NaN where a record lacks them): the episode's hours and units, which
#: pooled figures (ratios of sums, as a report pools them: :mod:`econmotor.analysis.operating_point`) need.
COUNT_COLUMNS: tuple[str, ...] = ("hours", "units_completed", "units_attempted", "errors")


@dataclass(frozen=True)
class RunInfo:
    """Who produced a group of episodes: the run and the sweep cell it belongs to."""

    run_id: str
    task_id: str = ""
    backend: str = ""
    objective: str = ""
    datapacks: tuple[str, ...] = ()
    seed: int | None = None
    cell_key: str | None = None
    commanded_speed_m_per_s: float | None = None  # the course's commanded speed, m/s (walkers)

    def to_dict(self) -> dict[str, Any]:
        return {"run_id": self.run_id, "task_id": self.task_id, "backend": self.backend,
                "objective": self.objective, "datapacks": list(self.datapacks), "seed": self.seed,
                "cell_key": self.cell_key, "commanded_speed_m_per_s": self.commanded_speed_m_per_s}


@dataclass(frozen=True)
class EpisodeTable:
    """Episodes sorted by run: episode ``i`` belongs to ``runs[run_index[i]]``.

    Attributes:
        runs: one entry per run, each with at least one episode.
        run_index: int64 (N,), non-decreasing.
        columns: name -> float64 (N,) for every name in :data:`METRIC_COLUMNS`.
        catastrophic: bool (N,).
        energy_price_usd_per_kwh: float64 (N,); NaN where unknown.
        counts: name -> float64 (N,) for every name in :data:`COUNT_COLUMNS`; NaN where unknown
            (a name left out is unknown in every episode).
    """

    runs: tuple[RunInfo, ...]
    run_index: np.ndarray
    columns: Mapping[str, np.ndarray]
    catastrophic: np.ndarray
    energy_price_usd_per_kwh: np.ndarray
    counts: Mapping[str, np.ndarray] = field(default_factory=dict)
    run_starts: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        n = len(self.run_index)
        for name in METRIC_COLUMNS:
            if name not in self.columns or self.columns[name].shape != (n,):
                raise ConfigError("<episodes>", name, f"column missing or not of length {n}")
        counts = {name: np.asarray(self.counts.get(name, np.full(n, np.nan)), dtype=np.float64)
                  for name in COUNT_COLUMNS}
        if any(c.shape != (n,) for c in counts.values()):
            raise ConfigError("<episodes>", "counts", f"count column not of length {n}", COUNT_COLUMNS)
        object.__setattr__(self, "counts", counts)
        if self.catastrophic.shape != (n,) or self.energy_price_usd_per_kwh.shape != (n,):
            raise ConfigError("<episodes>", "catastrophic", f"column not of length {n}")
        if n and (np.any(np.diff(self.run_index) < 0) or self.run_index[0] != 0):
            raise ConfigError("<episodes>", "run_index", "episodes must be sorted by run, starting at 0")
        counts = np.bincount(self.run_index, minlength=len(self.runs)) if n else np.zeros(len(self.runs))
        if len(counts) != len(self.runs) or np.any(counts == 0):
            raise ConfigError("<episodes>", "run_index", "every run needs at least one episode")
        for name in ("mpl_units_per_hour", "error_rate", "energy_wh", "wage_parity"):
            if not np.all(np.isfinite(self.columns[name])):
                raise ConfigError("<episodes>", name, "must be finite in every episode")
        object.__setattr__(self, "run_starts", np.flatnonzero(np.r_[True, np.diff(self.run_index) != 0])
                           if n else np.zeros(0, dtype=np.int64))

    @property
    def num_episodes(self) -> int:
        return len(self.run_index)

    @property
    def num_runs(self) -> int:
        return len(self.runs)

    def episode_counts(self) -> np.ndarray:
        """Episodes per run, int64 (R,)."""
        return np.diff(np.r_[self.run_starts, self.num_episodes])

    def run_means(self, values: np.ndarray) -> np.ndarray:
        """Mean of ``values`` ((N,) or (N, k)) over each run's episodes: (R,) or (R, k)."""
        sums = np.add.reduceat(values, self.run_starts, axis=0)
        counts = self.episode_counts()
        return sums / (counts if values.ndim == 1 else counts[:, None])

    @classmethod
    def from_arrays(cls, runs: Sequence[RunInfo], run_index: np.ndarray, *,
                    catastrophic: np.ndarray | None = None,
                    energy_price_usd_per_kwh: np.ndarray | float | None = None,
                    **columns: np.ndarray) -> EpisodeTable:
        """Build from arrays (sorted into run order here); missing novelty/risk columns are 0, missing
        count columns (:data:`COUNT_COLUMNS`) unknown."""
        run_index = np.asarray(run_index, dtype=np.int64)
        n = len(run_index)
        order = np.argsort(run_index, kind="stable")
        used, run_index = np.unique(run_index[order], return_inverse=True)
        counts = {name: np.asarray(columns.pop(name), dtype=np.float64).reshape(n)[order]
                  for name in COUNT_COLUMNS if name in columns}
        cols = {}
        for name in METRIC_COLUMNS:
            default = np.zeros(n) if name in ("novelty_score", "risk_score") else None
            value = columns.pop(name, default)
            if value is None:
                raise ConfigError("<episodes>", name, "missing column", METRIC_COLUMNS)
            cols[name] = np.asarray(value, dtype=np.float64).reshape(n)[order]
        if columns:
            raise ConfigError("<episodes>", next(iter(columns)), "unknown column", METRIC_COLUMNS)
        cat = np.zeros(n, bool) if catastrophic is None else np.asarray(catastrophic, bool)[order]
        price = np.full(n, np.nan) if energy_price_usd_per_kwh is None else \
            np.broadcast_to(np.asarray(energy_price_usd_per_kwh, dtype=np.float64), (n,))[order]
        return cls(tuple(runs[i] for i in used), run_index.astype(np.int64), cols, cat, np.array(price), counts)

    @classmethod
    def from_records(cls, records: Iterable[Mapping[str, Any]], source: str = "<episodes>",
                     default_price_usd_per_kwh: float | None = None,
                     default_run_id: str | None = None) -> EpisodeTable:
        """Build from episode records (JSONL lines, shadow records or summaries carrying the run fields).

        ``default_run_id`` names the run of shadow records that carry none (their run directory).
        """
        runs: dict[str, RunInfo] = {}
        positions: dict[str, int] = {}
        index: list[int] = []
        values: dict[str, list[float]] = {name: [] for name in (*METRIC_COLUMNS, *COUNT_COLUMNS)}
        cat: list[bool] = []
        price: list[float] = []
        for line, rec in enumerate(records, 1):
            where = f"{source}:{line}"
            fmt = rec.get("format", EPISODE_FORMAT)
            if fmt == SHADOW_EPISODE_FORMAT:
                rec = {"run_id": default_run_id, **shadow_episode_record(rec, where)}
            elif fmt != EPISODE_FORMAT:
                raise ConfigError(where, "format", f"unsupported episode format {fmt!r}",
                                  [EPISODE_FORMAT, SHADOW_EPISODE_FORMAT])
            run_id = rec.get("run_id")
            if run_id is None:
                raise ConfigError(where, "run_id", "every episode record needs the id of its run")
            run_id = str(run_id)
            if run_id not in runs:
                runs[run_id] = _run_info(rec, where)
                positions[run_id] = len(positions)
            index.append(positions[run_id])
            for name, value in {**_episode_values(rec, where), **_episode_counts(rec, where)}.items():
                values[name].append(value)
            cat.append(is_catastrophic(rec))
            p = rec.get("energy_price_usd_per_kwh", default_price_usd_per_kwh)
            price.append(math.nan if p is None else float(p))
        if not index:
            raise ConfigError(source, None, "no episodes found; record or export some runs first")
        return cls.from_arrays(list(runs.values()), np.array(index), catastrophic=np.array(cat),
                               energy_price_usd_per_kwh=np.array(price),
                               **{k: np.array(v) for k, v in values.items()})

    def records(self) -> list[dict[str, Any]]:
        """One JSON-ready dict per episode in the export format (inf/NaN as null)."""
        out = []
        counts = self.episode_counts()
        episode_in_run = np.arange(self.num_episodes) - np.repeat(self.run_starts, counts)
        for i in range(self.num_episodes):
            rec: dict[str, Any] = {"format": EPISODE_FORMAT, **self.runs[self.run_index[i]].to_dict(),
                                   "episode_index": int(episode_in_run[i])}
            for name in METRIC_COLUMNS:
                rec[name] = finite_or_none(self.columns[name][i])
            for name in COUNT_COLUMNS:
                rec[name] = finite_or_none(self.counts[name][i])
            rec["catastrophic"] = bool(self.catastrophic[i])
            rec["energy_price_usd_per_kwh"] = finite_or_none(self.energy_price_usd_per_kwh[i])
            out.append(rec)
        return out


def shadow_episode_record(rec: Mapping[str, Any], where: str = "<shadow episode>") -> dict[str, Any]:
    """A shadow-mode episode record as an episode record: its econ summary plus the run fields."""
    econ = rec.get("econ")
    if not isinstance(econ, Mapping):
        raise ConfigError(where, "econ", "a shadow episode record needs its econ summary")
    vector = rec.get("objective_vector") or []
    out = {**econ, "task_id": rec.get("task_id") or "", "backend": "shadow",
           "objective": "w[" + ",".join(f"{float(v):g}" for v in vector) + "]",
           "episode_index": rec.get("episode"),
           "energy_price_usd_per_kwh": rec.get("energy_price_usd_per_kwh")}
    if rec.get("run_id") is not None:
        out["run_id"] = rec["run_id"]
    return out


def finite_or_none(value: float) -> float | None:
    """A float for JSON: non-finite values become ``None`` (JSON has no inf/NaN)."""
    value = float(value)
    return value if math.isfinite(value) else None


def _run_info(rec: Mapping[str, Any], where: str) -> RunInfo:
    packs = rec.get("datapacks") or ()
    if isinstance(packs, str):
        packs = [p for p in packs.replace(",", " ").split() if p]
    if not isinstance(packs, (list, tuple)):
        raise ConfigError(where, "datapacks", f"expected a list of datapack ids, got {packs!r}")
    seed, speed = rec.get("seed"), rec.get("commanded_speed_m_per_s")
    try:
        speed = None if speed is None else float(speed)
    except (TypeError, ValueError):
        raise ConfigError(where, "commanded_speed_m_per_s", f"expected a speed in m/s, got {speed!r}") from None
    return RunInfo(run_id=str(rec["run_id"]), task_id=str(rec.get("task_id") or ""),
                   backend=str(rec.get("backend") or ""), objective=str(rec.get("objective") or ""),
                   datapacks=tuple(str(p) for p in packs), seed=None if seed is None else int(seed),
                   cell_key=rec.get("cell_key"), commanded_speed_m_per_s=speed)


def _episode_values(rec: Mapping[str, Any], where: str) -> dict[str, float]:
    def read(*names: str, default: float | None = None) -> float:
        for name in names:
            if rec.get(name) is not None:
                return float(rec[name])
        if default is None:
            raise ConfigError(where, names[0], "missing episode metric", names)
        return default

    try:
        out = {
            "mpl_units_per_hour": read(*SUMMARY_ALIASES["mpl"]),
            "error_rate": read(*SUMMARY_ALIASES["error_rate"]),
            "energy_wh": read("energy_wh", "energy_Wh", "Wh"),
            "energy_wh_per_unit": read("energy_wh_per_unit", "energy_Wh_per_unit", default=math.inf),
            "wage_parity": read("wage_parity"),
            "novelty_score": read("novelty_score", "novelty", default=0.0),
            "risk_score": read("risk_score", default=0.0),
        }
    except (TypeError, ValueError) as exc:
        raise ConfigError(where, None, f"episode metrics must be numbers: {exc}") from exc
    return out


def _episode_counts(rec: Mapping[str, Any], where: str) -> dict[str, float]:
    """The count columns of a record (NaN where absent): ``hours`` (else ``episode_length_s`` / 3600),
    ``units_attempted`` (else ``units_completed + errors``), as :func:`econmotor.economics.uncertainty.assess`
    reads an episode."""
    def read(name: str) -> float:
        value = rec.get(name)
        try:
            return math.nan if value is None else float(value)
        except (TypeError, ValueError):
            raise ConfigError(where, name, f"expected a number, got {value!r}") from None

    hours = read("hours")
    if math.isnan(hours):
        hours = read("episode_length_s") / 3600.0
    units, errors = read("units_completed"), read("errors")
    attempted = read("units_attempted")
    return {"hours": hours, "units_completed": units, "errors": errors,
            "units_attempted": units + errors if math.isnan(attempted) else attempted}


def _decoded_lines(fh: Any, path: Path) -> Iterable[tuple[int, str]]:
    """``enumerate(fh, 1)``, with a binary (non UTF-8) file a ConfigError naming the line."""
    number = 0
    try:
        for number, text in enumerate(fh, 1):
            yield number, text
    except UnicodeDecodeError as exc:
        raise ConfigError(f"{path}:{number + 1}", None, f"not UTF-8 text ({exc.reason}); "
                          "expected JSON lines") from None


def read_episodes_jsonl(path: str | Path, default_price_usd_per_kwh: float | None = None) -> EpisodeTable:
    """Read a JSONL export (format in the module docstring)."""
    path = Path(path)
    if not path.is_file():
        raise ConfigError(path, None, "episode file not found; write one with `econmotor solve --export-jsonl`")

    def lines() -> Iterable[dict[str, Any]]:
        with path.open(encoding="utf-8") as fh:
            for number, text in _decoded_lines(fh, path):
                if not text.strip():
                    continue
                try:
                    rec = json.loads(text)
                except json.JSONDecodeError as exc:
                    raise ConfigError(f"{path}:{number}", None, f"not valid JSON: {exc.msg}") from exc
                if not isinstance(rec, dict):
                    raise ConfigError(f"{path}:{number}", None, "each line must be a JSON object")
                yield rec

    return EpisodeTable.from_records(lines(), str(path), default_price_usd_per_kwh,
                                     default_run_id=path.resolve().parent.name)


def write_episodes_jsonl(table: EpisodeTable, path: str | Path) -> Path:
    """Write ``table`` as JSONL (atomically: a temporary file renamed into place)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(path.suffix + ".tmp")
    with tmp.open("w", encoding="utf-8") as fh:
        for rec in table.records():
            fh.write(json.dumps(rec, allow_nan=False) + "\n")
    tmp.replace(path)
    return path
