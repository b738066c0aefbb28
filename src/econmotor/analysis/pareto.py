"""Pareto front of runs and its hypervolume.

Runs are compared on four criteria: MPL (units/h, higher is better), energy
(Wh per good unit, lower is better), error rate (lower is better) and risk
(mean ``risk_score``, lower is better). Internally every criterion is turned
into a *minimisation* by negating the ones to maximise, so ``a`` dominates ``b``
when ``a <= b`` in every coordinate and ``a < b`` in at least one.

Hypervolume is the Lebesgue measure of the region dominated by the front and
bounded by a reference point ``r`` (in the original units; MPL's bound is a
floor, the others ceilings)::

    HV(P, r) = vol( union_{p in P} [p_1, r_1] x ... x [p_d, r_d] )   (minimisation form)

computed *exactly*. In 3-D and 4-D on a grid: the distinct x and y coordinates
of the points cut the (x, y) box into cells; ``Z[i, j]``, the lowest z of a point
dominating cell ``(i, j)``, is a 2-D prefix minimum (``np.minimum.accumulate`` along
both axes) of the points' z placed on the grid, and the 3-D volume is
``sum(cell area * (r_z - Z))``. In 4-D the points are swept by the last coordinate
(HSO slicing, While et al. 2006): each point lowers ``Z`` on the quarter-plane it
dominates, and the slab to the next point adds its depth times the 3-D volume so far.
Cost O(n^3) array operations in 4-D with no Python loop deeper than one level:
0.1 s for 400 mutually non-dominated runs, 13-19x faster than the recursive HSO
it replaces (``benchmarks/hypervolume.py``). Other dimensions use HSO slicing down to a 2-D sweep.
Points not strictly better than the
reference in every coordinate contribute nothing and are dropped first.
The default reference (:func:`default_reference_point`) is MPL 0 units/h,
error rate 1, risk 1 (or the worst observed risk if larger), and 1.1 x the
worst finite energy observed; the value used is always reported.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from econmotor.errors import ConfigError

#: criterion -> +1 to maximise, -1 to minimise.
PARETO_CRITERIA: dict[str, int] = {
    "mpl_units_per_hour": +1,
    "energy_wh_per_unit": -1,
    "error_rate": -1,
    "risk_score": -1,
}


def pareto_mask(points_min: np.ndarray) -> np.ndarray:
    """Boolean (n,) mask of the non-dominated rows of ``points_min`` (all minimised).

    Equal points do not dominate each other, so duplicates on the front are all kept.
    Vectorised pairwise comparison: O(n^2 d) memory-light for fronts of a few thousand runs.
    """
    pts = np.asarray(points_min, dtype=np.float64)
    if pts.ndim != 2:
        raise ConfigError("<pareto>", None, f"expected an (n, d) array, got shape {pts.shape}")
    if len(pts) == 0:
        return np.zeros(0, dtype=bool)
    le = np.all(pts[:, None, :] <= pts[None, :, :], axis=2)   # le[j, i]: j <= i everywhere
    lt = np.any(pts[:, None, :] < pts[None, :, :], axis=2)    # lt[j, i]: j < i somewhere
    return ~np.any(le & lt, axis=0)


def hypervolume(points_min: np.ndarray, reference_min: Sequence[float]) -> float:
    """Exact hypervolume of ``points_min`` (minimised) against ``reference_min`` (see module doc)."""
    pts = np.asarray(points_min, dtype=np.float64)
    ref = np.asarray(reference_min, dtype=np.float64)
    if pts.ndim != 2 or (len(pts) and pts.shape[1] != len(ref)):
        raise ConfigError("<pareto>", "reference", f"points {pts.shape} and reference {ref.shape} disagree")
    if not np.all(np.isfinite(ref)):
        raise ConfigError("<pareto>", "reference", f"reference point must be finite, got {ref.tolist()}")
    pts = pts[np.all(pts < ref, axis=1)] if len(pts) else pts
    if len(pts) == 0:
        return 0.0
    return float(_hso(pts[pareto_mask(pts)], ref))


def _grid(pts: np.ndarray, ref: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Cell areas of the (x, y) grid cut by the points' coordinates, and each point's cell."""
    xs, ix = np.unique(pts[:, 0], return_inverse=True)
    ys, iy = np.unique(pts[:, 1], return_inverse=True)
    area = np.diff(np.r_[xs, ref[0]])[:, None] * np.diff(np.r_[ys, ref[1]])[None, :]
    return area, ix.reshape(-1), iy.reshape(-1), np.full(area.shape, ref[2])


def _hv3(pts: np.ndarray, ref: np.ndarray) -> float:
    area, ix, iy, z = _grid(pts, ref)
    np.minimum.at(z, (ix, iy), pts[:, 2])
    z = np.minimum.accumulate(np.minimum.accumulate(z, axis=0), axis=1)
    return float(np.sum(area * (ref[2] - z)))


def _hv4(pts: np.ndarray, ref: np.ndarray) -> float:
    pts = pts[np.argsort(pts[:, 3], kind="stable")]
    depths = np.diff(np.r_[pts[:, 3], ref[3]])
    area, ix, iy, z = _grid(pts, ref)
    volume = 0.0
    for i in range(len(pts)):
        block = z[ix[i]:, iy[i]:]
        np.minimum(block, pts[i, 2], out=block)
        if depths[i] > 0:
            volume += depths[i] * float(np.sum(area * (ref[2] - z)))
    return volume


def _hso(pts: np.ndarray, ref: np.ndarray) -> float:
    d = pts.shape[1]
    if d == 3:
        return _hv3(pts, ref)
    if d == 4:
        return _hv4(pts, ref)
    if d == 1:
        return float(ref[0] - pts[:, 0].min())
    if d == 2:
        pts = pts[np.lexsort((pts[:, 1], pts[:, 0]))]
        best_y = np.minimum.accumulate(pts[:, 1])
        widths = np.diff(np.r_[pts[:, 0], ref[0]])
        return float(np.sum(widths * (ref[1] - best_y)))
    pts = pts[np.argsort(pts[:, -1], kind="stable")]
    depths = np.diff(np.r_[pts[:, -1], ref[-1]])
    volume = 0.0
    for i in range(len(pts)):
        if depths[i] > 0:
            passed = pts[: i + 1, :-1]
            if d > 3:  # the 2-D sweep is exact with dominated points; higher levels prune them
                passed = passed[pareto_mask(passed)]
            volume += depths[i] * _hso(passed, ref[:-1])
    return volume


def to_minimisation(values: np.ndarray, criteria: Sequence[str] = tuple(PARETO_CRITERIA)) -> np.ndarray:
    """Negate the columns of criteria to maximise so every column is minimised."""
    signs = np.array([-PARETO_CRITERIA[c] for c in criteria], dtype=np.float64)
    return np.asarray(values, dtype=np.float64) * signs


def default_reference_point(values: np.ndarray) -> dict[str, float]:
    """Reference point in original units for ``values`` (runs x the four criteria)."""
    values = np.asarray(values, dtype=np.float64)
    energy = values[:, 1][np.isfinite(values[:, 1])] if len(values) else np.zeros(0)
    risk = values[:, 3] if len(values) else np.zeros(0)
    return {
        "mpl_units_per_hour": 0.0,
        "energy_wh_per_unit": float(1.1 * energy.max()) if energy.size and energy.max() > 0 else 1.0,
        "error_rate": 1.0,
        "risk_score": float(max(1.0, risk.max())) if risk.size else 1.0,
    }


@dataclass(frozen=True)
class ParetoFront:
    """The non-dominated runs and their hypervolume.

    Attributes:
        criteria: criterion names, in column order (see :data:`PARETO_CRITERIA`).
        indices: run indices on the front, in input order.
        reference_point: criterion -> bound used for the hypervolume (original units).
        hypervolume: in the product of the criteria's units (units/h x Wh/unit x 1 x 1).
    """

    criteria: tuple[str, ...]
    indices: tuple[int, ...]
    reference_point: dict[str, float]
    hypervolume: float

    def to_dict(self) -> dict:
        return {"criteria": {c: ("max" if PARETO_CRITERIA[c] > 0 else "min") for c in self.criteria},
                "indices": list(self.indices), "reference_point": dict(self.reference_point),
                "hypervolume": self.hypervolume,
                "hypervolume_method": "exact, hypervolume by slicing objectives (HSO)"}


def pareto_front(values: np.ndarray, reference_point: dict[str, float] | None = None) -> ParetoFront:
    """Front and hypervolume of ``values`` (runs x the four criteria of :data:`PARETO_CRITERIA`).

    Args:
        values: (R, 4) array in original units: MPL, Wh per unit, error rate, risk.
        reference_point: bounds per criterion; missing ones come from :func:`default_reference_point`.
    """
    criteria = tuple(PARETO_CRITERIA)
    values = np.asarray(values, dtype=np.float64).reshape(-1, len(criteria))
    ref = default_reference_point(values)
    for key, bound in (reference_point or {}).items():
        if key not in ref:
            raise ConfigError("<pareto>", f"reference_point.{key}", "unknown criterion", criteria)
        ref[key] = float(bound)
    pts = to_minimisation(values, criteria)
    # inf energy (no good unit) sorts last; NaN would break dominance, so treat it as worst.
    pts = np.where(np.isnan(pts), np.inf, pts)
    mask = pareto_mask(pts)
    ref_min = to_minimisation(np.array([[ref[c] for c in criteria]]), criteria)[0]
    return ParetoFront(criteria, tuple(int(i) for i in np.flatnonzero(mask)), ref,
                       hypervolume(pts[mask], ref_min))
