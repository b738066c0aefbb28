"""make_motor_backend: a registry of backend names -> constructors (like Gymnasium's ``make``).

Backends are imported lazily, so a missing optional dependency only matters
when that backend is asked for.
"""

from __future__ import annotations

import importlib
from collections.abc import Mapping
from typing import Any

from econmotor.errors import BackendError, UnknownNameError
from econmotor.motor_backend.base import MotorBackendBase

#: the default ``--motor-backend`` of the commands that train.
DEFAULT_BACKEND = "mujoco"

_REGISTRY: dict[str, str] = {
    "mujoco": "econmotor.motor_backend.mujoco.backend:MujocoBackend",
    "dishwashing": "econmotor.motor_backend.dishwashing.backend:DishwashingBackend",
    "holosoma": "econmotor.motor_backend.holosoma.backend:HolosomaBackend",
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
        return getattr(importlib.import_module(module_name), attr)
    except ImportError as exc:
        raise BackendError(f"motor backend '{name}' cannot be imported: {exc}") from exc


def make_motor_backend(name: str, **kwargs: Any) -> MotorBackendBase:
    """Construct the backend registered as ``name`` with keyword arguments (``task_files``,
    ``runs_dir``, then the backend's own); unknown names list the known ones."""
    return backend_class(name)(**kwargs)


def environment_options(name: str, environ: Mapping[str, str]) -> dict[str, str]:
    """The constructor keywords that backend ``name`` takes from environment variables (its
    ``environment_options``), read from ``environ``: called at the edge, never inside a backend."""
    return {keyword: environ[variable] for variable, keyword in backend_class(name).environment_options.items()
            if environ.get(variable)}
