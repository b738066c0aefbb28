"""Checkpoints of the mjx backend's learner: params, optimizer state, normaliser, rng, step count.

One ``.npz`` per checkpoint (``checkpoints/ckpt_<N>_steps.npz``) holding the flattened pytree
leaves ``leaf_0000 ...``, the run's PRNG key and a JSON header (step count, leaf shapes).
Loading unflattens into the structure of a freshly built learner, so a checkpoint of other
hyperparameters (other layer sizes) is refused instead of silently misread. Writes go to a
temporary file first and are moved into place with ``os.replace`` (atomic on POSIX): a run
killed mid-write leaves the previous checkpoint intact.
"""

from __future__ import annotations

import json
import os
import re
import zipfile
from pathlib import Path
from typing import Any

import jax
import numpy as np

from econmotor.errors import BackendError

CHECKPOINT_DIR = "checkpoints"
_CKPT_RE = re.compile(r"ckpt_(\d+)_steps\.npz$")


def checkpoint_path(run_dir: str | Path, steps: int) -> Path:
    return Path(run_dir) / CHECKPOINT_DIR / f"ckpt_{int(steps)}_steps.npz"


def save_tree(path: str | Path, tree: Any, key: jax.Array, steps: int, extra: dict[str, Any] | None = None) -> Path:
    """Write ``tree`` (any pytree of arrays), ``key`` and ``steps`` to ``path`` atomically."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    leaves = [np.asarray(leaf) for leaf in jax.tree_util.tree_leaves(tree)]
    header = {"steps": int(steps), "shapes": [list(a.shape) for a in leaves], **(extra or {})}
    arrays = {f"leaf_{i:04d}": a for i, a in enumerate(leaves)}
    tmp = path.with_name(path.name + ".tmp")
    with open(tmp, "wb") as fh:
        np.savez(fh, header=np.asarray(json.dumps(header)), key=np.asarray(key), **arrays)
        fh.flush()
        os.fsync(fh.fileno())
    os.replace(tmp, path)
    return path


def load_tree(path: str | Path, template: Any) -> tuple[Any, jax.Array, int, dict[str, Any]]:
    """``(tree, key, steps, header)`` from ``path``, shaped like ``template``; BackendError if it does not fit."""
    path = Path(path)
    try:
        with np.load(path) as data:
            header = json.loads(str(data["header"]))
            n = len(header["shapes"])
            leaves = [data[f"leaf_{i:04d}"] for i in range(n)]
            key = data["key"]
    except (OSError, KeyError, ValueError, zipfile.BadZipFile) as exc:
        raise BackendError(f"cannot read checkpoint {path}: {exc}") from exc
    t_leaves, treedef = jax.tree_util.tree_flatten(template)
    shapes_ok = len(t_leaves) == len(leaves) and all(
        np.shape(a) == np.shape(b) for a, b in zip(t_leaves, leaves, strict=True))
    if not shapes_ok:
        raise BackendError(f"checkpoint {path} does not match the run's network (other hyperparameters?); "
                           "start a new --output-dir")
    tree = jax.tree_util.tree_unflatten(treedef, [jax.numpy.asarray(a, dtype=np.asarray(t).dtype)
                                                  for a, t in zip(leaves, t_leaves, strict=True)])
    return tree, jax.numpy.asarray(key), int(header["steps"]), header


def latest_checkpoint(run_dir: str | Path) -> tuple[Path, int] | None:
    """The newest readable ``checkpoints/ckpt_<N>_steps.npz`` and its N (unreadable ones skipped)."""
    found = []
    for path in (Path(run_dir) / CHECKPOINT_DIR).glob("ckpt_*_steps.npz"):
        m = _CKPT_RE.search(path.name)
        if m:
            found.append((int(m.group(1)), path))
    for steps, path in sorted(found, reverse=True):
        try:
            with zipfile.ZipFile(path) as zf:
                if zf.testzip() is None:
                    return path, steps
        except (zipfile.BadZipFile, OSError):
            continue
    return None
