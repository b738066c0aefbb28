"""Running agreement between two reward streams: Pearson and Spearman correlation.

:class:`RunningCorrelation` keeps every pair (two float64 arrays that grow by
doubling, so an append costs O(1)) and the Welford co-moments, so

- ``pearson()`` is exact and O(1): ``C_xy / sqrt(C_xx * C_yy)`` with
  ``C_xy = sum (x - mean_x)(y - mean_y)`` updated per pair;
- ``spearman(window)`` is the Pearson correlation of the ranks (average ranks
  for ties, as ``scipy.stats.spearmanr``) over all pairs or the last ``window``.

Both are ``nan`` until two pairs with non-zero spread exist.
"""

from __future__ import annotations

import math

import numpy as np


def _ranks(values: np.ndarray) -> np.ndarray:
    """Average ranks (ties share the mean of their positions)."""
    order = np.argsort(values, kind="mergesort")
    sorted_values = values[order]
    ranks = np.empty(len(values), dtype=np.float64)
    ranks[order] = np.arange(len(values), dtype=np.float64)
    unique, inverse, counts = np.unique(sorted_values, return_inverse=True, return_counts=True)
    if len(unique) < len(values):
        starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
        mean_rank = starts + (counts - 1) / 2.0
        ranks[order] = mean_rank[inverse]
    return ranks


def pearson_of(x: np.ndarray, y: np.ndarray) -> float:
    """Pearson correlation of two arrays; nan without spread."""
    if len(x) < 2:
        return math.nan
    dx, dy = x - x.mean(), y - y.mean()
    denom = math.sqrt(float(dx @ dx) * float(dy @ dy))
    return float(dx @ dy) / denom if denom > 0 else math.nan


def spearman_of(x: np.ndarray, y: np.ndarray) -> float:
    """Spearman rank correlation of two arrays; nan without spread."""
    if len(x) < 2:
        return math.nan
    return pearson_of(_ranks(x), _ranks(y))


class RunningCorrelation:
    """Pearson (exact, streaming) and Spearman (on demand) between paired values."""

    def __init__(self, capacity: int = 1024) -> None:
        self._x = np.empty(max(2, capacity))
        self._y = np.empty(max(2, capacity))
        self.count = 0
        self._mean_x = self._mean_y = 0.0
        self._cxx = self._cyy = self._cxy = 0.0

    def add(self, x: float, y: float) -> None:
        """Add one pair."""
        if self.count == len(self._x):
            self._x = np.concatenate([self._x, np.empty_like(self._x)])
            self._y = np.concatenate([self._y, np.empty_like(self._y)])
        self._x[self.count], self._y[self.count] = x, y
        self.count += 1
        dx, dy = x - self._mean_x, y - self._mean_y
        self._mean_x += dx / self.count
        self._mean_y += dy / self.count
        self._cxx += dx * (x - self._mean_x)
        self._cyy += dy * (y - self._mean_y)
        self._cxy += dx * (y - self._mean_y)

    @property
    def x(self) -> np.ndarray:
        return self._x[: self.count]

    @property
    def y(self) -> np.ndarray:
        return self._y[: self.count]

    def pearson(self) -> float:
        """Pearson correlation over every pair so far (streaming co-moments)."""
        denom = math.sqrt(self._cxx * self._cyy) if self._cxx > 0 and self._cyy > 0 else 0.0
        return self._cxy / denom if denom > 0 else math.nan

    def spearman(self, window: int | None = None) -> float:
        """Spearman correlation over every pair, or the last ``window`` pairs."""
        start = 0 if window is None else max(0, self.count - int(window))
        return spearman_of(self._x[start: self.count], self._y[start: self.count])

    def pearson_window(self, window: int) -> float:
        """Pearson correlation over the last ``window`` pairs."""
        start = max(0, self.count - int(window))
        return pearson_of(self._x[start: self.count], self._y[start: self.count])
