"""The jobs the main interpreter hands to .venv-holosoma's runner: typed, serialised once, parsed once.

The backend builds one of :class:`ProbeJob`, :class:`TrainJob` or :class:`EvaluateJob`;
:func:`.host.jobs.run_job` writes it as JSON (:meth:`HolosomaJob.to_json`:
``{"action": ..., <its fields>}``) and the runner reads it back with :func:`parse_job`. A file that is
not a job of a known action, lacks a field, has one it does not know, or holds a value of the wrong
type is a ConfigError naming the file and the field. It imports in both interpreters (the main one and
.venv-holosoma's numpy 1.x): neither Holosoma nor torch.
"""

from __future__ import annotations

import json
import typing
from dataclasses import MISSING, asdict, dataclass, fields
from typing import Any, ClassVar

from econmotor.errors import ConfigError
from econmotor.motor_backend.holosoma.host.plan import RunPlan


@dataclass(frozen=True)
class HolosomaJob:
    """A job for the runner; ``action`` names it (and its log file, ``<log_name>.log``)."""

    action: ClassVar[str] = ""

    @property
    def log_name(self) -> str:
        """The job's log and job-file stem in its run directory."""
        return self.action

    def to_json(self) -> str:
        """The job as the runner reads it: ``{"action": ..., <fields>}`` (nested dataclasses as objects)."""
        return json.dumps({"action": self.action, **asdict(self)}, indent=2)


@dataclass(frozen=True)
class ProbeJob(HolosomaJob):
    """Report CUDA and which simulators import."""

    action: ClassVar[str] = "probe"


@dataclass(frozen=True)
class Overlay:
    """The econ overlay's reward terms: ``weights`` (overlay key -> reward weight, ``overlay_gain * scale``) and
    ``params`` (the terms' shared parameters: progress mode, unit duration, novelty rate, the meter)."""

    weights: dict[str, float]
    params: dict[str, Any]


@dataclass(frozen=True)
class TrainJob(HolosomaJob):
    """Train a Holosoma preset (``experiment``) with the econ overlay and the datapacks' overrides.

    Attributes:
        run_dir / run_name: where Holosoma writes (``<run_dir>/holosoma``) and its experiment's name.
        plan: the request adapted to the machine (:class:`.host.plan.RunPlan`: preset, algorithm, simulator,
            device, envs, iterations, CPU sizing); seed: Holosoma's seed.
        motion_task: the task tracks a motion clip (whole-body tracking).
        overlay: :class:`Overlay`; overrides: ``HolosomaOverrides.to_dict()`` (randomization, curriculum,
            terrain, motion_file, evaluation).
    """

    action: ClassVar[str] = "train"
    run_dir: str
    run_name: str
    plan: RunPlan
    seed: int
    motion_task: bool
    overlay: Overlay
    overrides: dict[str, Any]


@dataclass(frozen=True)
class EvaluateJob(HolosomaJob):
    """Holosoma's ``eval_agent`` on ``checkpoint`` for ``num_steps`` control steps of ``episode_length_s`` s
    episodes on ``simulator``, with the recording callback."""

    action: ClassVar[str] = "evaluate"
    run_dir: str
    checkpoint: str
    num_steps: int
    episode_length_s: float
    seed: int
    simulator: str


#: action -> job class
JOB_TYPES: dict[str, type[HolosomaJob]] = {cls.action: cls for cls in (ProbeJob, TrainJob, EvaluateJob)}

_PLAIN = {"int": int, "float": (int, float), "str": str, "bool": bool, "list": list, "tuple": list, "dict": dict}


def _build(cls: type, values: Any, source: str, where: str) -> Any:
    """``cls`` from a JSON object, every field present, known and of its declared type."""
    if not isinstance(values, dict):
        raise ConfigError(source, where or None, f"must be a JSON object, not {type(values).__name__}")
    known = {f.name: f for f in fields(cls)}
    unknown = sorted(set(values) - set(known))
    if unknown:
        raise ConfigError(source, f"{where}{unknown[0]}", f"not a field of a {cls.__name__}", sorted(known))
    hints = typing.get_type_hints(cls)
    kwargs = {}
    for name, f in known.items():
        key = f"{where}{name}"
        if name not in values:
            if f.default is MISSING and f.default_factory is MISSING:
                raise ConfigError(source, key, f"missing: a {cls.__name__} needs it")
            continue
        kind, value = hints[name], values[name]
        if isinstance(kind, type) and hasattr(kind, "__dataclass_fields__"):
            value = _build(kind, value, source, f"{key}.")
        else:
            name_of_type = getattr(typing.get_origin(kind) or kind, "__name__", "")
            plain = _PLAIN.get(name_of_type)
            if plain is not None and (not isinstance(value, plain) or (plain is not bool and isinstance(value, bool))):
                raise ConfigError(source, key, f"must be a JSON {name_of_type}, not {value!r}")
            if name_of_type == "tuple":
                value = tuple(value)
        kwargs[name] = value
    return cls(**kwargs)


def parse_job(text: str, source: str = "<job>") -> HolosomaJob:
    """The job a JSON text holds (:meth:`HolosomaJob.to_json`); a ConfigError naming ``source`` and the field."""
    try:
        values = json.loads(text)
    except json.JSONDecodeError as exc:
        raise ConfigError(source, None, f"not a JSON job: {exc}") from None
    if not isinstance(values, dict) or values.get("action") not in JOB_TYPES:
        action = values.get("action") if isinstance(values, dict) else None
        raise ConfigError(source, "action", f"unknown job action {action!r}", sorted(JOB_TYPES))
    cls = JOB_TYPES[values["action"]]
    return _build(cls, {k: v for k, v in values.items() if k != "action"}, source, "")
