"""A Holosoma run directory's record: the trained ``policy.onnx`` (Holosoma's export with econmotor's metadata
attached), ``run_config.json`` with what the training job logged, and reading it back (a run written before
``run_config.json``: its ``policy.json``).
"""

from __future__ import annotations

import json
import shutil
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from econmotor.couriers.onnx_metadata import ECONMOTOR_PREFIX
from econmotor.motor_backend.run_dir import RUN_CONFIG_FILE, read_run_config, write_run_config

LEGACY_MANIFEST = "policy.json"  # the run record before run_config.json


def attach_econmotor_metadata(onnx_path: str | Path, metadata: dict[str, Any]) -> None:
    """Add ``econmotor_<key>`` entries (JSON values) to an ONNX file's metadata, replacing old ones."""
    import onnx

    model = onnx.load(str(onnx_path))
    keep = [p for p in model.metadata_props if not p.key.startswith(ECONMOTOR_PREFIX)]
    del model.metadata_props[:]
    model.metadata_props.extend(keep)
    for key, value in metadata.items():
        entry = model.metadata_props.add()
        entry.key, entry.value = f"{ECONMOTOR_PREFIX}{key}", json.dumps(value, default=str)
    tmp = Path(str(onnx_path) + ".tmp")
    onnx.save(model, str(tmp))
    tmp.replace(onnx_path)


def training_log(outcome: Any, result: Mapping[str, Any]) -> dict[str, Any]:
    """What a training job's protocol logged: the econ terms, reward terms, wall time and iteration times."""
    return {"econ_term_log": {k: v for c in outcome.curve for k, v in c.get("econ", {}).items()},
            "reward_terms": result["reward_terms"], "train_wall_s": outcome.wall_s,
            "econ_term_seconds": result.get("econ_term_seconds", 0.0),
            "iteration_times_s": [{"collection_s": c.get("collection_s"), "learn_s": c.get("learn_s")}
                                  for c in outcome.curve]}


def record_run(run_dir: Path, ours: dict[str, Any], result: dict[str, Any], extra: dict[str, Any],
               backend: str, policy_file: str) -> Path:
    """The run's ``policy_file`` (Holosoma's export with econmotor's metadata ``ours`` attached) and its
    ``run_config.json``; returns the ONNX's path."""
    attach_econmotor_metadata(result["onnx"], ours)
    policy_onnx = run_dir / policy_file  # the run's policy, where every backend keeps its final one
    shutil.copyfile(result["onnx"], policy_onnx)
    write_run_config(run_dir, {
        **ours, "checkpoint": result["checkpoint"], "onnx": str(policy_onnx),
        "holosoma_onnx": result["onnx"], "experiment_dir": result["experiment_dir"],
        "episode_length_s": result["episode_length_s"], "control_dt_s": result["control_dt_s"], **extra},
        backend)
    return policy_onnx


def read_run_record(policy_id: str, backend: str) -> dict[str, Any]:
    """The run's ``run_config.json`` (a run written before it had one: its ``policy.json``)."""
    legacy = Path(policy_id) / LEGACY_MANIFEST
    if not (Path(policy_id) / RUN_CONFIG_FILE).is_file() and legacy.is_file():
        return json.loads(legacy.read_text(encoding="utf-8"))
    return read_run_config(policy_id, backend)
