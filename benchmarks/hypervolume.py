"""Exact 4-D hypervolume: the grid sweep in ``econmotor.analysis.pareto`` over recursive HSO.

Both are exact; the script checks they agree and prints the time of each and the ratio,
measured side by side on the same fronts of mutually non-dominated points (the worst case:
every point is on the front). The HSO reference is the slicing recursion the grid replaced
(sort by the last coordinate, recurse on the passed points, 2-D sweep at the bottom).

    .venv/bin/python benchmarks/hypervolume.py [--sizes 100 200 400]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from econmotor.analysis.pareto import hypervolume, pareto_mask

#: the smallest run (tests/integration/test_benchmarks.py)
SMOKE_ARGS: list[str] = ["--sizes", "8"]


def hso(pts: np.ndarray, ref: np.ndarray) -> float:
    """Recursive hypervolume by slicing objectives (While et al. 2006), the reference."""
    d = pts.shape[1]
    if d == 2:
        pts = pts[np.lexsort((pts[:, 1], pts[:, 0]))]
        best_y = np.minimum.accumulate(pts[:, 1])
        return float(np.sum(np.diff(np.r_[pts[:, 0], ref[0]]) * (ref[1] - best_y)))
    pts = pts[np.argsort(pts[:, -1], kind="stable")]
    depths = np.diff(np.r_[pts[:, -1], ref[-1]])
    volume = 0.0
    for i in range(len(pts)):
        if depths[i] > 0:
            passed = pts[: i + 1, :-1]
            if d > 3:
                passed = passed[pareto_mask(passed)]
            volume += depths[i] * hso(passed, ref[:-1])
    return volume


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[100, 200, 400])
    args = parser.parse_args()
    rng = np.random.default_rng(0)
    ref = np.full(4, 3.0)
    for n in args.sizes:
        pts = rng.random((n, 4))
        pts[:, 3] = 2.0 - pts[:, :3].sum(axis=1)  # on a plane: no point dominates another
        t0 = time.perf_counter()
        grid = hypervolume(pts, ref)
        t1 = time.perf_counter()
        reference = hso(pts, ref)
        t2 = time.perf_counter()
        assert abs(grid - reference) <= 1e-9 * abs(reference), (grid, reference)
        print(f"{n:>5} front points: grid {t1 - t0:.3f} s, HSO {t2 - t1:.3f} s, "
              f"ratio HSO/grid {(t2 - t1) / (t1 - t0):.1f}x (equal to {abs(grid - reference):.1e})")


if __name__ == "__main__":
    main()
