"""Write data/mocap/logging_clip_01.npz: the example datapack's whole-body-tracking clip.

The clip is the first ``--seconds`` of the box lift-and-carry motion that Holosoma
ships (``holosoma/data/motions/g1_29dof/whole_body_tracking/sub3_largebox_003_mj.npz``,
Apache-2.0), stored as float32 in Holosoma's motion format: ``fps``, ``joint_pos``
(root xyz + root quat wxyz + 29 joints), ``joint_vel`` (root 6 + 29), ``body_pos_w``,
``body_quat_w`` (wxyz), ``body_lin_vel_w``, ``body_ang_vel_w``, ``joint_names``,
``body_names``. Run with any Python that has numpy, from the repository root::

    .venv/bin/python scripts/make_example_clip.py
"""

from __future__ import annotations

import argparse
import glob
from pathlib import Path

import numpy as np

SOURCE_GLOB = ".venv-holosoma/lib/python3*/site-packages/holosoma/data/motions/g1_29dof/whole_body_tracking/" \
              "sub3_largebox_003_mj.npz"
FLOAT_KEYS = ("joint_pos", "joint_vel", "body_pos_w", "body_quat_w", "body_lin_vel_w", "body_ang_vel_w")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--source", help="Holosoma motion npz (default: the one in .venv-holosoma)")
    parser.add_argument("--seconds", type=float, default=3.0)
    parser.add_argument("--output", default="data/mocap/logging_clip_01.npz")
    args = parser.parse_args()
    source = args.source or next(iter(sorted(glob.glob(SOURCE_GLOB))), None)
    if source is None:
        raise SystemExit(f"no source clip: run `make holosoma` first or pass --source (looked for {SOURCE_GLOB})")
    with np.load(source) as data:
        fps = int(np.asarray(data["fps"]).reshape(-1)[0])
        frames = min(len(data["joint_pos"]), max(2, round(args.seconds * fps)))
        out = {k: data[k][:frames].astype(np.float32) for k in FLOAT_KEYS}
        out["fps"] = np.array([fps], dtype=np.int64)
        out["joint_names"] = data["joint_names"]
        out["body_names"] = data["body_names"]
    path = Path(args.output)
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(path, **out)
    print(f"wrote {path}: {frames} frames at {fps} fps ({frames / fps:.2f} s), {path.stat().st_size} bytes")


if __name__ == "__main__":
    main()
