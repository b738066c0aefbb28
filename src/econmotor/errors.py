"""Exceptions raised by econmotor library code.

Library code raises these; the CLI renders them. A :class:`ConfigError` always
names the file (or source), the key and what is allowed, so a user can fix the
input without reading code.
"""

from __future__ import annotations

import difflib
from collections.abc import Iterable
from pathlib import Path


class EconmotorError(Exception):
    """Base class of every error econmotor raises on purpose."""


class ConfigError(EconmotorError, ValueError):
    """A configuration value is missing, unknown, of the wrong type or out of range.

    Args:
        source: the file path (or a label such as ``"<objective>"``) the value came from.
        key: dotted path of the offending key, e.g. ``"domain_randomization.friction_range"``.
        message: what is wrong.
        allowed: what would be accepted (a list of names or a phrase).
    """

    def __init__(
        self,
        source: str | Path | None,
        key: str | None,
        message: str,
        allowed: str | Iterable[str] | None = None,
    ) -> None:
        self.source = str(source) if source is not None else "<config>"
        self.key = key
        self.detail = message
        if allowed is not None and not isinstance(allowed, str):
            allowed = ", ".join(sorted(str(a) for a in allowed))
        self.allowed = allowed
        where = self.source + (f": key '{key}'" if key else "")
        text = f"{where}: {message}"
        if allowed:
            text += f" (allowed: {allowed})"
        super().__init__(text)


class UnknownNameError(EconmotorError, KeyError):
    """A registry (tasks, backends, presets, datapacks) was asked for an id it does not know."""

    def __init__(self, kind: str, name: str, known: Iterable[str]) -> None:
        known = sorted(known)
        self.kind, self.name, self.known = kind, name, known
        hint = did_you_mean(name, known)
        super().__init__(f"unknown {kind} '{name}'{hint}; known {kind}s: {', '.join(known)}")

    def __str__(self) -> str:  # KeyError would repr() the message
        return self.args[0]


class BackendError(EconmotorError, RuntimeError):
    """A motor backend failed while training, evaluating or deploying."""


class RegistryError(EconmotorError, RuntimeError):
    """The run registry (database) cannot be used as asked."""


def did_you_mean(name: str, candidates: Iterable[str]) -> str:
    """Return ``" (did you mean 'x'?)"`` for the closest candidate, or ``""``."""
    close = difflib.get_close_matches(str(name), [str(c) for c in candidates], n=1, cutoff=0.6)
    return f" (did you mean '{close[0]}'?)" if close else ""
