"""Run directories and seeds: one meaning everywhere.

``output_dir`` *is* the run directory (default: a new ``<runs_dir>/<task>-<UTC time>-s<seed>-<pid>``,
:func:`new_run_dir`), its record is ``run_config.json``, and ``policy_id`` names that directory
(or, for a backend that imports policies, a policy file or shipped name), so any process can
evaluate or deploy it. Evaluation seeds follow one rule: episode ``i`` of an evaluation seeded
``s`` is seeded ``s + i``; the evaluation right after training uses ``s = seed +
TRAINING_EVAL_SEED_OFFSET``, a report's evaluation run ``s = seed + REPORT_EVAL_SEED_OFFSET`` and
evaluation-driven training's held-out evaluations ``s = seed + SELECTION_SEED_OFFSET``, so none
shares an episode with another.
"""

from __future__ import annotations

import json
import os
import time
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from econmotor.errors import ConfigError

#: the file every trained run directory (mujoco, mjx) starts with: its task, settings and hyperparameters
RUN_CONFIG_FILE = "run_config.json"
#: an evaluation's record in its output directory: metrics, episodes, config with the provenance
EVALUATION_FILE = "evaluation.json"


def read_run_config(run_dir: str | Path, backend: str | None = None, task_id: str | None = None) -> dict[str, Any]:
    """The ``run_config.json`` of a run directory; a ConfigError names what is wrong.

    ``backend``: the run must be that backend's (the ``backend`` every backend records with
    :func:`write_run_config`; None: any backend's run). ``task_id``: the policy must have been
    trained on it.
    """
    path = Path(run_dir) / RUN_CONFIG_FILE
    a_backend = f"{'an' if backend == 'mjx' else 'a'} {backend}" if backend else "a trained"  # "an mjx", "a mujoco"
    if not path.is_file():
        raise ConfigError(str(run_dir), None, f"not {a_backend} run directory (no {RUN_CONFIG_FILE})")
    config = json.loads(path.read_text(encoding="utf-8"))
    recorded = config.get("backend")
    if recorded is None:
        raise ConfigError(str(path), "backend", "missing: every backend records its name there (a run written by "
                          "hand or by an older econmotor); add the backend that trained it")
    if backend is not None and recorded != backend:
        raise ConfigError(str(path), "backend", f"a '{recorded}' run, not {a_backend} one")
    if task_id is not None and config.get("task_id") != task_id:
        raise ConfigError(str(path), "task_id", f"policy was trained on '{config.get('task_id')}', not '{task_id}'")
    return config


def write_run_config(run_dir: Path, config: Mapping[str, Any], backend: str) -> None:
    """Write ``run_config.json`` with ``backend`` recorded, atomically (a temporary file renamed over it):
    readers see the old or the new."""
    tmp = run_dir / (RUN_CONFIG_FILE + ".tmp")
    tmp.write_text(json.dumps({**config, "backend": backend}, indent=2, default=str), encoding="utf-8")
    tmp.replace(run_dir / RUN_CONFIG_FILE)


def check_resume_request(run_dir: Path, previous: Mapping[str, Any], task_id: str,
                         hyperparameters: Mapping[str, Any] | None) -> None:
    """A resumed run continues its recorded task and hyperparameters; asking for others is an error
    (start a new run directory to change them)."""
    source = str(run_dir / RUN_CONFIG_FILE)
    if previous.get("task_id") != task_id:
        raise ConfigError(source, "task_id", f"cannot resume a '{previous.get('task_id')}' run as '{task_id}'")
    recorded = previous.get("hyperparameters") or {}
    for key, value in (hyperparameters or {}).items():
        if key in recorded and recorded[key] != json.loads(json.dumps(value, default=str)):
            raise ConfigError(source, f"hyperparameters.{key}", f"the run was trained with {recorded[key]!r}; "
                              f"resume keeps the recorded value, not {value!r} (use a new --output-dir)")


#: the evaluation right after training seeds its episodes from ``seed + TRAINING_EVAL_SEED_OFFSET``.
TRAINING_EVAL_SEED_OFFSET = 10_000
#: the evaluation right after training is recorded in ``<run_dir>/TRAINING_EVAL_DIR/evaluation.json``
#: (:data:`EVALUATION_FILE`).
TRAINING_EVAL_DIR = "eval"
#: a report's evaluation run seeds its episodes from ``seed + REPORT_EVAL_SEED_OFFSET`` (fresh episodes).
REPORT_EVAL_SEED_OFFSET = 1_000
#: held-out evaluations of evaluation-driven training (``selection.py``) seed episode i with
#: ``seed + SELECTION_SEED_OFFSET + i``: the same episodes for every checkpoint, apart from the others.
SELECTION_SEED_OFFSET = 50_000


def utc_stamp() -> str:
    """The UTC time to the second, ``YYYYmmdd-HHMMSS``: with the process id, a folder name no other run takes."""
    return time.strftime("%Y%m%d-%H%M%S", time.gmtime())


def new_run_dir(runs_dir: str | Path, task_id: str, seed: int) -> Path:
    """A run directory of its own: ``<runs_dir>/<task>-<UTC time>-s<seed>-<pid>`` (never reused)."""
    return Path(runs_dir) / f"{task_id}-{utc_stamp()}-s{seed}-{os.getpid()}"
