"""Task catalog: one registry of task ids, shipped as YAML, extendable by user YAML.

Every ``*.yaml`` file in this package directory is loaded (each backend ships its
own file: ``dishwashing.yaml``, ``mujoco.yaml``, ...), then any user files in
order; a user file may add tasks or replace a shipped one whole. File schema::

    tasks:
      <task_id>:
        description: "..."
        unit: "clean dish"                 # the unit of work
        error_definition: "..."            # what counts as an error, how error rate is counted
        economics:                          # every number: value + source (unit is fixed per key)
          wage_human_usd_per_hour: {value: 18.0, source: "..."}
          ...
          battery_capacity_wh: {value: 421.2, source: "..."}   # optional: a robot on a battery (Wh),
          battery_recharge_h: {value: 1.5, source: "..."}      # hours on the charger per charge, and/or
          battery_swap_h: {value: 0.1, source: "..."}          # a pack swap's hours (used when given)
        backends:                           # backend name -> that backend's own settings
          dishwashing: {econ_preset: toy}
        locomotion: {robot: g1_29dof, ...}  # a card robot's walker task: its one place (locomotion/task.py)
        acceptance:                         # optional: what evaluation must show before a price
          max_error_rate: {value: 0.05, source: "..."}     # upper bound of the error rate (default: human's)
          min_units_per_hour: {value: 30, source: "..."}   # lower bound of MPL (default: any work)
          error_name: "broken dish"                        # one error, in sentences

A file may instead add one backend's entries to tasks other files define (``mjx.yaml``)::

    backend_entries:
      <backend>:
        <task_id>: {...}                    # becomes tasks.<task_id>.backends.<backend>
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field, replace
from functools import lru_cache
from pathlib import Path
from typing import Any

from econmotor.config.acceptance import Acceptance
from econmotor.config.loading import (
    as_float,
    as_str,
    check_keys,
    path_name,
    read_yaml_mapping,
    require_mapping,
)
from econmotor.config.task_economics import ECONOMICS_UNITS, TaskEconomics
from econmotor.errors import ConfigError, UnknownNameError

_PACKAGE_DIR = Path(__file__).parent
_TASK_KEYS = ("description", "unit", "error_definition", "economics", "backends", "tags", "acceptance", "locomotion")
_ACCEPTANCE_KEYS = ("max_error_rate", "min_units_per_hour", "error_name")


@dataclass(frozen=True)
class TaskSpec:
    """One catalog entry."""

    task_id: str
    description: str
    unit: str
    error_definition: str
    economics: TaskEconomics
    backends: Mapping[str, Mapping[str, Any]] = field(default_factory=dict)
    tags: tuple[str, ...] = ()
    source: str = "<builtin>"
    acceptance_rule: Acceptance | None = None
    #: a card robot's walker task: its robot, meter, course and reward terms, read by every backend that runs
    #: it (checked by :func:`econmotor.locomotion.task.walker_settings`); None for any other task
    locomotion: Mapping[str, Any] | None = None

    @property
    def acceptance(self) -> Acceptance:
        """The catalog's acceptance rule, or the default (no worse than a human)."""
        return self.acceptance_rule or Acceptance.default_for(self.economics.error_rate_human)
    #: backend -> the file its entry came from, where not ``source`` (``backend_entries`` files)
    backend_sources: Mapping[str, str] = field(default_factory=dict)

    def backend_source(self, backend: str) -> str:
        """The file that holds this task's ``backend`` entry."""
        return self.backend_sources.get(backend, self.source)

    def backend_entry(self, backend: str) -> dict[str, Any]:
        """The backend's own settings for this task; a ConfigError if it cannot run it."""
        if backend not in self.backends:
            raise ConfigError(
                self.source,
                f"tasks.{self.task_id}.backends",
                f"task '{self.task_id}' has no entry for backend '{backend}'",
                list(self.backends),
            )
        return dict(self.backends[backend])


class TaskCatalog:
    """A registry of :class:`TaskSpec` by id (like Gymnasium's env registry)."""

    def __init__(self, tasks: Mapping[str, TaskSpec], user_ids: Iterable[str] = ()) -> None:
        self._tasks = dict(tasks)
        #: the ids a user's task file defined (their backend entries are checked by the factory)
        self.user_ids = frozenset(user_ids)

    def get(self, task_id: str) -> TaskSpec:
        try:
            return self._tasks[task_id]
        except KeyError:
            raise UnknownNameError("task id", task_id, self._tasks) from None

    def __contains__(self, task_id: object) -> bool:
        return task_id in self._tasks

    def ids(self, backend: str | None = None) -> list[str]:
        """Task ids, optionally only those with an entry for ``backend``."""
        return sorted(t for t, s in self._tasks.items() if backend is None or backend in s.backends)

    def __iter__(self):
        return iter(self._tasks.values())

    def __len__(self) -> int:
        return len(self._tasks)


def parse_task(task_id: str, data: Any, source: str | Path) -> TaskSpec:
    """Validate one task mapping from ``source`` into a :class:`TaskSpec`."""
    prefix = f"tasks.{task_id}"
    data = require_mapping(data, source, prefix)
    check_keys(data, _TASK_KEYS, source, prefix, required=("unit", "economics", "backends"))
    econ_raw = require_mapping(data["economics"], source, f"{prefix}.economics")
    check_keys(econ_raw, ECONOMICS_UNITS, source, f"{prefix}.economics")
    values: dict[str, Any] = {}
    sources: dict[str, str] = {}
    for name, entry in econ_raw.items():
        key = f"{prefix}.economics.{name}"
        entry = require_mapping(entry, source, key)
        check_keys(entry, ("value", "unit", "source"), source, key, required=("value", "source"))
        if "unit" in entry and entry["unit"] != ECONOMICS_UNITS[name]:
            raise ConfigError(source, f"{key}.unit", f"unit must be {ECONOMICS_UNITS[name]!r}, got {entry['unit']!r}")
        values[name] = as_float(entry["value"], source, f"{key}.value", allow_negative=False)
        sources[name] = as_str(entry["source"], source, f"{key}.source")
    try:
        economics = TaskEconomics(**values, sources=sources)
    except ConfigError as exc:
        raise ConfigError(source, f"{prefix}.economics.{exc.key}", exc.detail) from None
    backends_raw = require_mapping(data["backends"], source, f"{prefix}.backends")
    backends = {
        name: require_mapping(entry if entry is not None else {}, source, f"{prefix}.backends.{name}")
        if entry is not None
        else {}
        for name, entry in backends_raw.items()
    }
    tags = data.get("tags", [])
    if not isinstance(tags, list) or not all(isinstance(t, str) for t in tags):
        raise ConfigError(source, f"{prefix}.tags", "expected a list of strings")
    return TaskSpec(
        acceptance_rule=_parse_acceptance(data.get("acceptance"), economics, source, prefix),
        task_id=task_id,
        description=as_str(data.get("description", ""), source, f"{prefix}.description"),
        unit=as_str(data["unit"], source, f"{prefix}.unit"),
        error_definition=as_str(data.get("error_definition", ""), source, f"{prefix}.error_definition"),
        economics=economics,
        backends=backends,
        tags=tuple(tags),
        source=str(source),
        locomotion=require_mapping(data["locomotion"], source, f"{prefix}.locomotion") if "locomotion" in data
        else None,
    )


def _parse_acceptance(raw: Any, economics: TaskEconomics, source: str | Path, prefix: str) -> Acceptance | None:
    if raw is None:
        return None
    key = f"{prefix}.acceptance"
    raw = require_mapping(raw, source, key)
    check_keys(raw, _ACCEPTANCE_KEYS, source, key)
    default = Acceptance.default_for(economics.error_rate_human)
    values: dict[str, Any] = {"error_name": as_str(raw.get("error_name", "error"), source, f"{key}.error_name")}
    sources = dict(default.sources)
    for name in ("max_error_rate", "min_units_per_hour"):
        if name not in raw:
            values[name] = getattr(default, name)
            continue
        entry = require_mapping(raw[name], source, f"{key}.{name}")
        check_keys(entry, ("value", "source"), source, f"{key}.{name}", required=("value", "source"))
        values[name] = as_float(entry["value"], source, f"{key}.{name}.value", allow_negative=False)
        sources[name] = as_str(entry["source"], source, f"{key}.{name}.source")
    if values["max_error_rate"] > 1:
        raise ConfigError(source, f"{key}.max_error_rate.value", f"must be <= 1, got {values['max_error_rate']}")
    return Acceptance(values["max_error_rate"], values["min_units_per_hour"], values["error_name"], sources)


def read_task_file(path: str | Path) -> dict[str, TaskSpec]:
    """Read one catalog YAML file (schema in the module docstring)."""
    data = read_yaml_mapping(path)
    check_keys(data, ("tasks",), path, required=("tasks",))
    tasks = require_mapping(data["tasks"], path, "tasks")
    return {path_name(tid, path, f"tasks.{tid}"): parse_task(tid, entry, path) for tid, entry in tasks.items()}


def add_backend_entries(tasks: dict[str, TaskSpec], path: str | Path, data: Mapping[str, Any]) -> None:
    """Attach a ``backend_entries`` file's entries to the tasks already in ``tasks`` (in place)."""
    entries = require_mapping(data["backend_entries"], path, "backend_entries")
    for backend, per_task in entries.items():
        per_task = require_mapping(per_task, path, f"backend_entries.{backend}")
        for tid, entry in per_task.items():
            key = f"backend_entries.{backend}.{tid}"
            if tid not in tasks:
                raise ConfigError(path, key, f"no task '{tid}' to add a '{backend}' entry to", sorted(tasks))
            spec = tasks[tid]
            if backend in spec.backends:
                raise ConfigError(path, key, f"task '{tid}' already has a '{backend}' entry in {spec.source}")
            backends = {**spec.backends, str(backend): require_mapping(entry or {}, path, key)}
            tasks[tid] = replace(spec, backends=backends,
                                 backend_sources={**spec.backend_sources, str(backend): str(path)})


@lru_cache(maxsize=1)
def _builtin_tasks() -> dict[str, TaskSpec]:
    tasks: dict[str, TaskSpec] = {}
    entry_files = []
    for path in sorted(_PACKAGE_DIR.glob("*.yaml")):
        data = read_yaml_mapping(path)
        if "backend_entries" in data:
            check_keys(data, ("backend_entries",), path)
            entry_files.append((path, data))
            continue
        for tid, spec in read_task_file(path).items():
            if tid in tasks:
                raise ConfigError(path, f"tasks.{tid}", f"task id already defined in {tasks[tid].source}")
            tasks[tid] = spec
    for path, data in entry_files:  # after every task file: entries may name any shipped task
        add_backend_entries(tasks, path, data)
    return tasks


def load_catalog(user_files: Iterable[str | Path] = ()) -> TaskCatalog:
    """The shipped catalog plus ``user_files`` (later files replace earlier ids whole), parsed only.

    The backend entries of a user file's tasks (``user_ids``) are checked against the backends by
    :func:`econmotor.motor_backend.factory.load_checked_catalog`, which commands call once; the
    shipped entries are checked by the tests."""
    tasks = dict(_builtin_tasks())
    user_ids: set[str] = set()
    for path in user_files:
        added = read_task_file(path)
        tasks.update(added)
        user_ids.update(added)
    return TaskCatalog(tasks, user_ids)


def get_task(task_id: str, user_files: Iterable[str | Path] = ()) -> TaskSpec:
    """Look up one task id; an unknown id raises an error listing the known ones."""
    return load_catalog(user_files).get(task_id)
