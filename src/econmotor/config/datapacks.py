"""Datapacks: motion clips, domain randomization and curriculum, as YAML.

Schema (spec: motor_backends.md, plus tags)::

    id: logging_v1_base                 # required, unique
    description: "..."
    motion_clips:                       # npz reference trajectories, sampled by weight
      - path: data/mocap/clip_01.npz
        weight: 1.0
    domain_randomization:               # keys are validated by the backend that uses them
      terrain: "flat"
      friction_range: [0.5, 1.0]
    curriculum:
      initial_difficulty: 0.1
      max_difficulty: 1.0
    tags: [baseline]
    task_tags: [locomotion]             # tasks this pack is meant for
    robot_families: [humanoid]
    objective_hint: throughput          # a preset name, or free text ("prioritise throughput
                                        # on fragile items"): kept as written, shown in reports

Generic validation happens here (types, weights, difficulty in [0, 1]); each
backend validates the ``domain_randomization`` and ``curriculum`` keys it supports.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from econmotor.config.loading import as_float, as_str, check_keys, path_name, read_yaml_mapping, require_mapping
from econmotor.config.objective_profile import OBJECTIVE_PRESETS
from econmotor.errors import ConfigError, UnknownNameError

DATAPACK_KEYS = ("id", "description", "motion_clips", "domain_randomization", "curriculum",
                 "tags", "task_tags", "robot_families", "objective_hint")


@dataclass(frozen=True)
class MotionClipRef:
    """A reference trajectory file and its sampling weight."""

    path: str
    weight: float = 1.0

    def resolve(self, base_dir: str | Path | None = None) -> Path:
        """The clip's path: absolute as given, else relative to the cwd, else to ``base_dir``."""
        p = Path(self.path)
        if p.is_absolute() or p.exists() or base_dir is None:
            return p
        return Path(base_dir) / p


@dataclass(frozen=True)
class DatapackConfig:
    """One validated datapack."""

    id: str
    description: str = ""
    motion_clips: tuple[MotionClipRef, ...] = ()
    domain_randomization: dict[str, Any] = field(default_factory=dict)
    curriculum: dict[str, Any] = field(default_factory=dict)
    tags: tuple[str, ...] = ()
    task_tags: tuple[str, ...] = ()
    robot_families: tuple[str, ...] = ()
    objective_hint: str | None = None
    source: str = "<datapack>"

    @property
    def objective_hint_preset(self) -> str | None:
        """The hint when it names an objective preset, else ``None`` (free text, or no hint)."""
        return hint_preset(self.objective_hint)

    def to_dict(self) -> dict[str, Any]:
        """The YAML mapping (without ``source``); ``parse_datapack(to_dict())`` round-trips."""
        out: dict[str, Any] = {"id": self.id}
        if self.description:
            out["description"] = self.description
        if self.motion_clips:
            out["motion_clips"] = [{"path": c.path, "weight": c.weight} for c in self.motion_clips]
        if self.domain_randomization:
            out["domain_randomization"] = dict(self.domain_randomization)
        if self.curriculum:
            out["curriculum"] = dict(self.curriculum)
        for key in ("tags", "task_tags", "robot_families"):
            if getattr(self, key):
                out[key] = list(getattr(self, key))
        if self.objective_hint is not None:
            out["objective_hint"] = self.objective_hint
        return out

    @property
    def base_dir(self) -> Path | None:
        return Path(self.source).parent if not self.source.startswith("<") else None


@dataclass(frozen=True)
class DatapackBundle:
    """Several datapacks merged for one task: later packs' keys win."""

    task_id: str
    datapack_ids: tuple[str, ...] = ()
    motion_clips: tuple[MotionClipRef, ...] = ()
    domain_randomization: dict[str, Any] = field(default_factory=dict)
    curriculum: dict[str, Any] = field(default_factory=dict)
    tags: tuple[str, ...] = ()
    objective_hint: str | None = None
    sources: dict[str, str] = field(default_factory=dict)
    #: motion clip path -> datapack id it came from (for error messages)
    clip_origins: dict[str, str] = field(default_factory=dict)

    @property
    def objective_hint_preset(self) -> str | None:
        """The merged hint when it names an objective preset, else ``None``."""
        return hint_preset(self.objective_hint)


def hint_preset(hint: str | None) -> str | None:
    """``hint`` if it is an objective preset name (``throughput``, ...), else ``None``.

    Upstream datapacks carry free-text hints ("prioritise throughput on fragile items"):
    those are kept as written (stored, shown in reports), never an error.
    """
    return hint if hint in OBJECTIVE_PRESETS else None


def _str_list(value: Any, source: str | Path, key: str) -> tuple[str, ...]:
    if isinstance(value, str):
        value = [value]
    if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
        raise ConfigError(source, key, f"expected a list of strings, got {value!r}")
    return tuple(value)


def parse_datapack(data: Any, source: str | Path = "<datapack>") -> DatapackConfig:
    """Validate one datapack mapping (schema in the module docstring)."""
    data = require_mapping(data, source, None)
    check_keys(data, DATAPACK_KEYS, source, required=("id",))
    pack_id = path_name(as_str(data["id"], source, "id"), source, "id")
    if not pack_id.strip():
        raise ConfigError(source, "id", "must not be empty")
    clips_raw = data.get("motion_clips") or []
    if not isinstance(clips_raw, list):
        raise ConfigError(source, "motion_clips", f"expected a list of {{path, weight}}, got {clips_raw!r}")
    clips = []
    for i, clip in enumerate(clips_raw):
        key = f"motion_clips[{i}]"
        clip = require_mapping(clip, source, key)
        check_keys(clip, ("path", "weight"), source, key, required=("path",))
        weight = as_float(clip.get("weight", 1.0), source, f"{key}.weight", min_value=0.0)
        clips.append(MotionClipRef(as_str(clip["path"], source, f"{key}.path"), weight))
    if clips and sum(c.weight for c in clips) <= 0:
        raise ConfigError(source, "motion_clips", "clip weights must not all be zero")
    dr = require_mapping(data["domain_randomization"], source, "domain_randomization") \
        if data.get("domain_randomization") is not None else {}
    cur = require_mapping(data["curriculum"], source, "curriculum") if data.get("curriculum") is not None else {}
    for key in ("initial_difficulty", "max_difficulty"):
        if key in cur:
            as_float(cur[key], source, f"curriculum.{key}", min_value=0.0, max_value=1.0)
    if "initial_difficulty" in cur and "max_difficulty" in cur and cur["initial_difficulty"] > cur["max_difficulty"]:
        raise ConfigError(source, "curriculum.initial_difficulty", "must not exceed max_difficulty")
    hint = data.get("objective_hint")
    if hint is not None:
        hint = as_str(hint, source, "objective_hint")  # a preset name or free text, kept as written
        hint = hint if hint.strip() else None
    return DatapackConfig(
        id=pack_id,
        description=as_str(data.get("description", ""), source, "description"),
        motion_clips=tuple(clips),
        domain_randomization=dr,
        curriculum=cur,
        tags=_str_list(data.get("tags", []), source, "tags"),
        task_tags=_str_list(data.get("task_tags", []), source, "task_tags"),
        robot_families=_str_list(data.get("robot_families", []), source, "robot_families"),
        objective_hint=hint,
        source=str(source),
    )


def load_datapack_configs(paths: Iterable[str | Path]) -> list[DatapackConfig]:
    """Load datapack YAML files in order."""
    return [parse_datapack(read_yaml_mapping(p), p) for p in paths]


def save_datapack_config(config: DatapackConfig, path: str | Path) -> Path:
    """Write a datapack as YAML (atomically); ``load_datapack_configs([path])`` reads it back equal."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(path.suffix + ".tmp")
    tmp.write_text(yaml.safe_dump(config.to_dict(), sort_keys=False), encoding="utf-8")
    tmp.replace(path)
    return path


class DatapackProvider:
    """Resolves datapack ids for a task into one merged :class:`DatapackBundle`.

    Args:
        known: registered datapacks (e.g. shipped examples or ones recorded in the registry).
    """

    def __init__(self, known: Iterable[DatapackConfig] = ()) -> None:
        self._known: dict[str, DatapackConfig] = {}
        for config in known:
            self.register(config)

    def register(self, config: DatapackConfig) -> None:
        self._known[config.id] = config

    def known_ids(self) -> list[str]:
        return sorted(self._known)

    def resolve(
        self,
        task_id: str,
        ids: Sequence[str] = (),
        configs: Sequence[DatapackConfig] = (),
    ) -> DatapackBundle:
        """Merge datapacks in order: ``configs`` (explicit) are available alongside registered ones.

        ``ids`` selects and orders packs (duplicates dropped, first kept); with no ids every
        pack in ``configs`` is used in order. Later packs' ``domain_randomization`` and
        ``curriculum`` keys win; motion clips accumulate.
        """
        available = {**self._known, **{c.id: c for c in configs}}
        order = list(dict.fromkeys(ids)) if ids else list(dict.fromkeys(c.id for c in configs))
        packs = []
        for pack_id in order:
            if pack_id not in available:
                raise UnknownNameError("datapack id", pack_id, available)
            packs.append(available[pack_id])
        dr: dict[str, Any] = {}
        cur: dict[str, Any] = {}
        clips: list[MotionClipRef] = []
        origins: dict[str, str] = {}
        tags: list[str] = []
        hint = None
        for pack in packs:
            dr.update(pack.domain_randomization)
            cur.update(pack.curriculum)
            for clip in pack.motion_clips:
                resolved = MotionClipRef(str(clip.resolve(pack.base_dir)), clip.weight)
                clips.append(resolved)
                origins[resolved.path] = pack.id
            tags.extend(t for t in pack.tags if t not in tags)
            hint = pack.objective_hint or hint
        return DatapackBundle(
            task_id=task_id,
            datapack_ids=tuple(order),
            motion_clips=tuple(clips),
            domain_randomization=dr,
            curriculum=cur,
            tags=tuple(tags),
            objective_hint=hint,
            sources={p.id: p.source for p in packs},
            clip_origins=origins,
        )
