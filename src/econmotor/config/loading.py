"""Reading and validating YAML configs at the edge.

Every loader in econmotor goes through these helpers, so every bad input
raises :class:`econmotor.errors.ConfigError` naming the file, the key and what
is allowed: unknown keys (with a did-you-mean), wrong types, NaN/inf, negative
prices, empty or non-mapping files.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

import yaml

from econmotor.errors import ConfigError, did_you_mean


def read_yaml_mapping(path: str | Path) -> dict[str, Any]:
    """Read a YAML file whose top level must be a non-empty mapping with string keys."""
    path = Path(path)
    if not path.is_file():
        raise ConfigError(path, None, "file not found")
    try:
        data = yaml.safe_load(path.read_text(encoding="utf-8"))
    except (yaml.YAMLError, UnicodeDecodeError) as exc:
        raise ConfigError(path, None, f"not valid YAML: {exc}") from exc
    return require_mapping(data, path, None)


def require_mapping(data: Any, source: str | Path, key: str | None) -> dict[str, Any]:
    """Check that ``data`` is a non-empty mapping with string keys and return it as a dict."""
    if data is None:
        raise ConfigError(source, key, "is empty; expected a mapping of keys to values")
    if not isinstance(data, Mapping):
        raise ConfigError(source, key, f"expected a mapping, got {type(data).__name__}")
    for k in data:
        if not isinstance(k, str):
            raise ConfigError(source, join_key(key, str(k)), "keys must be strings")
    return dict(data)


def join_key(prefix: str | None, key: str) -> str:
    return f"{prefix}.{key}" if prefix else key


def check_keys(
    data: Mapping[str, Any],
    allowed: Iterable[str],
    source: str | Path,
    prefix: str | None = None,
    required: Iterable[str] = (),
) -> None:
    """Reject keys not in ``allowed`` (with a did-you-mean) and missing ``required`` keys."""
    allowed = list(allowed)
    for k in data:
        if k not in allowed:
            raise ConfigError(
                source, join_key(prefix, k), "unknown key" + did_you_mean(k, allowed), allowed
            )
    for k in required:
        if k not in data:
            raise ConfigError(source, join_key(prefix, k), "missing required key", allowed)


def as_float(
    value: Any,
    source: str | Path,
    key: str,
    *,
    min_value: float | None = None,
    max_value: float | None = None,
    allow_negative: bool = True,
) -> float:
    """Validate a finite real number (bools are rejected) within optional bounds."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ConfigError(source, key, f"expected a number, got {type(value).__name__} {value!r}")
    value = float(value)
    if not math.isfinite(value):
        raise ConfigError(source, key, f"must be finite, got {value}")
    if not allow_negative and value < 0:
        raise ConfigError(source, key, f"must not be negative, got {value}", ">= 0")
    if min_value is not None and value < min_value:
        raise ConfigError(source, key, f"must be >= {min_value}, got {value}")
    if max_value is not None and value > max_value:
        raise ConfigError(source, key, f"must be <= {max_value}, got {value}")
    return value


def as_int(value: Any, source: str | Path, key: str, *, min_value: int | None = None) -> int:
    """Validate an integer (bools and non-integral floats are rejected)."""
    if isinstance(value, bool):
        raise ConfigError(source, key, f"expected an integer, got {value!r}")
    if isinstance(value, float) and value.is_integer():
        value = int(value)
    if not isinstance(value, int):
        raise ConfigError(source, key, f"expected an integer, got {type(value).__name__} {value!r}")
    if min_value is not None and value < min_value:
        raise ConfigError(source, key, f"must be >= {min_value}, got {value}")
    return value


def as_str(value: Any, source: str | Path, key: str, allowed: Iterable[str] | None = None) -> str:
    """Validate a string, optionally one of ``allowed``."""
    if not isinstance(value, str):
        raise ConfigError(source, key, f"expected a string, got {type(value).__name__} {value!r}")
    if allowed is not None:
        allowed = list(allowed)
        if value not in allowed:
            raise ConfigError(source, key, f"'{value}' is not allowed" + did_you_mean(value, allowed), allowed)
    return value


def as_range(
    value: Any,
    source: str | Path,
    key: str,
    *,
    min_value: float | None = None,
    max_value: float | None = None,
) -> tuple[float, float]:
    """Validate ``[low, high]`` with ``low <= high``, both finite and within bounds."""
    if not isinstance(value, (list, tuple)) or len(value) != 2:
        raise ConfigError(source, key, f"expected a [low, high] pair, got {value!r}")
    low = as_float(value[0], source, key, min_value=min_value, max_value=max_value)
    high = as_float(value[1], source, key, min_value=min_value, max_value=max_value)
    if low > high:
        raise ConfigError(source, key, f"low {low} is greater than high {high}")
    return (low, high)
