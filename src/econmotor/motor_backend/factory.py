"""make_motor_backend: a registry of backend names -> constructors (like Gymnasium's ``make``).

Backends are imported lazily, so a missing optional dependency only matters
when that backend is asked for.
"""

from __future__ import annotations

import importlib
from typing import Any

from econmotor.errors import BackendError, UnknownNameError
from econmotor.motor_backend.base import MotorBackend

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


def make_motor_backend(name: str, **kwargs: Any) -> MotorBackend:
    """Construct the backend registered as ``name``; unknown names list the known ones."""
    if name not in _REGISTRY:
        raise UnknownNameError("motor backend", name, _REGISTRY)
    module_name, _, attr = _REGISTRY[name].partition(":")
    try:
        cls = getattr(importlib.import_module(module_name), attr)
    except ImportError as exc:
        raise BackendError(f"motor backend '{name}' cannot be imported: {exc}") from exc
    return cls(**kwargs)
