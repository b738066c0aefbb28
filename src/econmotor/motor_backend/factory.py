"""make_motor_backend: a registry of backend names -> constructors (like Gymnasium's ``make``).

Backends are imported lazily, so a missing optional dependency only matters
when that backend is asked for.
"""

from __future__ import annotations

import importlib
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

from econmotor.errors import BackendError, ConfigError, UnknownNameError, did_you_mean
from econmotor.motor_backend.base import MotorBackendBase
from econmotor.tasks.catalog import TaskCatalog, TaskSpec, load_catalog

#: the default ``--motor-backend`` of the commands that train.
DEFAULT_BACKEND = "mujoco"

_REGISTRY: dict[str, str] = {
    "mujoco": "econmotor.motor_backend.mujoco.backend:MujocoBackend",
    "dishwashing": "econmotor.motor_backend.dishwashing.backend:DishwashingBackend",
    "holosoma": "econmotor.motor_backend.holosoma.host.backend:HolosomaBackend",
    "mjx": "econmotor.motor_backend.mjx.backend:MjxBackend",
}


def register_motor_backend(name: str, target: str) -> None:
    """Register ``"package.module:ClassName"`` under ``name`` (replaces an existing entry)."""
    if ":" not in target:
        raise ValueError(f"target must look like 'package.module:ClassName', got {target!r}")
    _REGISTRY[name] = target


def known_backends() -> list[str]:
    return sorted(_REGISTRY)


def backend_class(name: str) -> type[MotorBackendBase]:
    """The class registered as ``name`` (imported now), whose declarations (capabilities, defaults,
    limits, files) can be read before anything is built; unknown names list the known ones."""
    if name not in _REGISTRY:
        raise UnknownNameError("motor backend", name, _REGISTRY)
    module_name, _, attr = _REGISTRY[name].partition(":")
    try:
        cls = getattr(importlib.import_module(module_name), attr)
    except ImportError as exc:
        raise BackendError(f"motor backend '{name}' cannot be imported: {exc}") from exc
    if not (isinstance(cls, type) and issubclass(cls, MotorBackendBase)):
        raise BackendError(f"motor backend '{name}' ({_REGISTRY[name]}) does not extend "
                           "econmotor.motor_backend.base.MotorBackendBase, the class that owns the contract")
    return cls


def check_backend_entries(spec: TaskSpec) -> None:
    """Every ``backends.<name>`` entry of ``spec`` names a registered backend and passes that
    backend's own check (``check_task_entry``: its keys and value types); a ConfigError names the
    file and key. A backend whose dependencies are not installed here cannot be asked: its entry is
    checked where it runs."""
    known = known_backends()
    for name in spec.backends:
        key = f"tasks.{spec.task_id}.backends.{name}"
        if name not in known:
            raise ConfigError(spec.backend_source(name), key, "unknown motor backend" + did_you_mean(name, known),
                              known)
        try:
            backend = backend_class(name)
        except BackendError:
            continue
        backend.check_task_entry(spec)


def load_checked_catalog(user_files: Iterable[str | Path] = ()) -> TaskCatalog:
    """The task catalog with ``user_files``, their tasks' backend entries checked against the
    backends: what a command loads once and hands to the backend it builds."""
    catalog = load_catalog(user_files)
    for task_id in sorted(catalog.user_ids):
        check_backend_entries(catalog.get(task_id))
    return catalog


def make_motor_backend(name: str, **kwargs: Any) -> MotorBackendBase:
    """Construct the backend registered as ``name`` with keyword arguments (``task_files``,
    ``runs_dir``, ``catalog``, then the backend's own); without a ``catalog`` the checked catalog
    of ``task_files`` is loaded here; unknown names list the known ones."""
    cls = backend_class(name)
    kwargs.setdefault("catalog", load_checked_catalog(kwargs.get("task_files", ())))
    return cls(**kwargs)


def environment_options(name: str, environ: Mapping[str, str]) -> dict[str, str]:
    """The constructor keywords that backend ``name`` takes from environment variables (its
    ``environment_options``), read from ``environ``: called at the edge, never inside a backend."""
    return {keyword: environ[variable] for variable, keyword in backend_class(name).environment_options.items()
            if environ.get(variable)}
