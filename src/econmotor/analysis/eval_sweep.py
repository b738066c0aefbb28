"""Evaluation sweeps: a policy that exists, evaluated at each commanded speed x datapacks x seed, every cell
recorded in the registry as an ``eval`` run (run by :func:`econmotor.analysis.sweep.run_sweep`).

A walker's operating point is its commanded speed: the same gait walks its course faster or slower, drawing
more or less energy per leg. An :class:`EvalCell` evaluates one policy (a shipped name such as
``holosoma:g1_29dof/ppo``, an ONNX file or a run directory) with ``backend.evaluate_policy`` at one speed
(the backend's ``course_speed_m_per_s``: ``capabilities.course_speed``). Its key::

    cell_key = sha256(canonical JSON of {"kind": "eval", task_id, backend, policy, policy_digest,
                      commanded_speed_m_per_s, datapack ids and their validated YAML content, seed,
                      eval_episodes, eval_options})[:20]

``policy_digest`` is the sha256 of the policy's file (an ONNX file; a run directory's ``run_config.json``),
so a policy replaced at the same path is a new cell; ``eval_options`` are backend constructor keywords that
change what is measured (e.g. the holosoma backend's ``eval_episode_length_s``). Episode ``i`` of a cell
seeded ``s`` is seeded ``s + REPORT_EVAL_SEED_OFFSET + i``: the episodes ``econmotor compare --seed s`` and a
report's evaluation walk, apart from any a run saw in training or held-out selection. The run's config records
``commanded_speed_m_per_s``, which ``econmotor solve`` shows beside each candidate
(:mod:`econmotor.analysis.operating_point`).
"""

from __future__ import annotations

import hashlib
import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar

from econmotor.config.datapacks import DatapackConfig
from econmotor.config.objective_profile import ObjectiveVector
from econmotor.couriers.policy_import import NAME_PREFIX
from econmotor.errors import ConfigError
from econmotor.motor_backend.base import ProgressFn
from econmotor.motor_backend.results import MotorEvalResult
from econmotor.motor_backend.run_dir import REPORT_EVAL_SEED_OFFSET, RUN_CONFIG_FILE
from econmotor.objectives.economic_objective import EconomicObjectiveSpec
from econmotor.objectives.loader import objective_from_vector
from econmotor.valuation import default_objective_vector


def evaluation_objective() -> EconomicObjectiveSpec:
    """The objective an evaluation cell records (RewardBuilder's default vector, named 'default', as
    ``econmotor compare`` records): a policy that exists is evaluated once, and ``econmotor solve``
    scores its episodes under every objective."""
    return objective_from_vector(ObjectiveVector.from_list(default_objective_vector()), name="default")


def policy_fingerprint(policy: str) -> tuple[str, str]:
    """``(policy id, digest)``: a shipped name as given with no digest; a path made absolute, with the
    sha256 of the ONNX file or of the run directory's ``run_config.json`` ("" where there is none)."""
    if policy.startswith(NAME_PREFIX):
        return policy, ""
    path = Path(policy).resolve()
    source = path / RUN_CONFIG_FILE if path.is_dir() else path
    digest = hashlib.sha256(source.read_bytes()).hexdigest() if source.is_file() else ""
    return str(path), digest


@dataclass(frozen=True)
class EvalCell:
    """One evaluation of the grid: ``policy`` at ``command_speed_m_per_s`` (None: the task catalog's speed)."""

    run_kind: ClassVar[str] = "eval"

    task_id: str
    backend: str
    policy: str
    datapacks: tuple[DatapackConfig, ...]
    seed: int
    command_speed_m_per_s: float | None = None
    eval_episodes: int = 5
    policy_digest: str = ""
    eval_options: tuple[tuple[str, Any], ...] = ()

    @property
    def datapack_ids(self) -> tuple[str, ...]:
        return tuple(p.id for p in self.datapacks)

    @property
    def key(self) -> str:
        """Deterministic id of the cell (module docstring); equal inputs give equal keys."""
        payload = {"kind": "eval", "task_id": self.task_id, "backend": self.backend, "policy": self.policy,
                   "policy_digest": self.policy_digest, "commanded_speed_m_per_s": self.command_speed_m_per_s,
                   "datapacks": [p.to_dict() for p in self.datapacks], "seed": self.seed,
                   "eval_episodes": self.eval_episodes, "eval_options": dict(self.eval_options)}
        text = json.dumps(payload, sort_keys=True, separators=(",", ":"))
        return hashlib.sha256(text.encode()).hexdigest()[:20]

    def run_config(self) -> dict[str, Any]:
        """What the registry stores in the run's config."""
        return {"cell_key": self.key, "sweep": True, "policy": self.policy, "policy_digest": self.policy_digest,
                "commanded_speed_m_per_s": self.command_speed_m_per_s, "eval_episodes": self.eval_episodes,
                "eval_seed": self.seed + REPORT_EVAL_SEED_OFFSET, "eval_options": dict(self.eval_options)}

    def start_fields(self) -> dict[str, Any]:
        """``registry.start_run``'s keywords for this cell."""
        return {"objective": evaluation_objective(), "datapack_ids": self.datapack_ids, "config": self.run_config(),
                "seed": self.seed, "notes": "econmotor sweep (evaluation)", "policy_path": self.policy}

    def execute(self, output_dir: str, progress: ProgressFn, backend_options: Mapping[str, Any]) -> MotorEvalResult:
        """Evaluate the policy into ``<output_dir>/<cell key>`` on a backend built with ``backend_options``,
        the cell's ``eval_options`` and its speed."""
        from econmotor.motor_backend.factory import make_motor_backend

        options = {**backend_options, **dict(self.eval_options)}
        if self.command_speed_m_per_s is not None:
            options["course_speed_m_per_s"] = self.command_speed_m_per_s
        backend = make_motor_backend(self.backend, **options)
        return backend.evaluate_policy(self.policy, self.task_id, evaluation_objective(), self.eval_episodes,
                                       self.seed + REPORT_EVAL_SEED_OFFSET, datapack_configs=list(self.datapacks),
                                       output_dir=str(Path(output_dir) / self.key), progress=progress)

    def mean_j(self, episodes: Sequence[Any]) -> float | None:
        """None: an evaluation has no objective of its own (``econmotor solve`` scores it under each)."""
        return None


def check_speeds(backend: str, speeds: Sequence[float | None]) -> None:
    """Each speed finite and > 0, and a backend that walks a course at a commanded speed where one is given."""
    from econmotor.motor_backend.factory import backend_class, known_backends

    for speed in speeds:
        if speed is not None and not (math.isfinite(speed) and speed > 0):
            raise ConfigError("<sweep>", "command_speed_m_per_s", f"must be a finite speed > 0 m/s, got {speed}")
    if any(s is not None for s in speeds) and not backend_class(backend).capabilities.course_speed:
        raise ConfigError("<sweep>", "command_speed_m_per_s", f"backend '{backend}' walks no course at a commanded "
                          "speed", [b for b in known_backends() if backend_class(b).capabilities.course_speed])


def plan_eval_sweep(task_id: str, backend: str, policy: str, speeds: Sequence[float | None],
                    datapack_groups: Sequence[Sequence[DatapackConfig]], seeds: Sequence[int], *,
                    eval_episodes: int = 5, eval_options: Mapping[str, Any] | None = None) -> list[EvalCell]:
    """The grid ``speeds x datapack_groups x seeds`` of ``policy`` (speed outermost, seed innermost).

    ``speeds``: commanded speeds in m/s (``[None]``: the task catalog's); ``eval_options``: backend constructor
    keywords that change what is measured (part of every key).
    """
    if not speeds or not seeds or not datapack_groups:
        raise ConfigError("<sweep>", None, "a sweep needs at least one speed, datapack group and seed")
    if eval_episodes < 1:
        raise ConfigError("<sweep>", "eval_episodes", f"must be >= 1, got {eval_episodes}")
    check_speeds(backend, speeds)
    policy_id, digest = policy_fingerprint(policy)
    options = tuple(sorted(dict(eval_options or {}).items()))
    cells = [EvalCell(task_id, backend, policy_id, tuple(g), int(s), None if v is None else float(v),
                      eval_episodes, digest, options)
             for v in speeds for g in datapack_groups for s in seeds]
    keys = [c.key for c in cells]
    if len(set(keys)) != len(keys):
        raise ConfigError("<sweep>", None, "the grid repeats a cell (same speed, datapacks and seed)")
    return cells
