"""The points of a large cloud inside an axis-aligned box, without looking at the others.

Tracking against a map registers each scan against the part of the map around its predicted
pose (:mod:`frisicp_core.window`); finding that part by testing every map point would cost a
pass over the whole map per scan. :class:`GridIndex` buckets the points once into the cells of
a regular grid (cell c = floor((x - low) / h) per axis, one integer key per cell, the points
sorted by key), so a box query touches only the cells the box meets and the points in them:

- the cells meeting the box are enumerated (their keys, in a range per axis) and looked up
  among the occupied ones by binary search (``np.searchsorted``);
- their points are gathered from the sorted order (each cell is one run of it) and tested
  against the box exactly;
- the result is sorted, so the window keeps the cloud's own (spatial) order.

The cell edge h is chosen so that the bounding box holds about :data:`POINTS_PER_CELL` points per
cell on average if the points filled it: a surface (a terrain, the walls of a room) fills few
of its bounding box's cells, so occupied cells hold more, a few dozen points typically. A box
whose cells outnumber the points is answered by a pass over all points instead (as fast then).

Memory: one int64 per point (the sorted order) and two per occupied cell: 16 MiB for 2,000,000
points. Building it sorts the cell keys once (about 0.3 s for 2,000,000 points).
"""

from __future__ import annotations

import numpy as np

from .similarity import FloatArray

# Points per cell of the bounding grid if the points filled it uniformly (see the module doc).
POINTS_PER_CELL = 8.0
# Fewest points a dimension's extent is compared with: a flat cloud (a planar map) must not get
# a zero-thickness bounding box, whose volume would make the cells vanishingly small.
_FLAT = 1e-3


class GridIndex:
    """The points of a cloud bucketed in a regular grid for box queries (module doc)."""

    def __init__(self, points: FloatArray) -> None:
        n, dim = points.shape
        self.points = points
        self.low = np.array([points[:, k].min() for k in range(dim)])
        high = np.array([points[:, k].max() for k in range(dim)])
        extent = high - self.low
        largest = float(extent.max()) or 1.0
        extent = np.maximum(extent, _FLAT * largest)
        volume = float(np.prod(extent))
        self.cell = (volume * POINTS_PER_CELL / max(n, 1)) ** (1.0 / dim)
        self.shape = np.floor(extent / self.cell).astype(np.int64) + 1
        keys = self._keys(self._cells(points))
        # Stable: each cell's points stay in ascending order, so a box's points are a few ascending
        # runs, which a stable (merging) sort puts in order several times faster than quicksort.
        self.order = np.argsort(keys, kind="stable")
        self.occupied, self.starts = np.unique(keys[self.order], return_index=True)
        self.ends = np.append(self.starts[1:], n)

    def box(self, low: FloatArray, high: FloatArray) -> np.ndarray:
        """Indices (ascending) of the points p with low <= p <= high on every axis."""
        first = np.maximum(self._cells(low[None])[0], 0)
        last = np.minimum(self._cells(high[None])[0], self.shape - 1)
        if np.any(last < first):
            return np.zeros(0, dtype=np.int64)
        counts = last - first + 1
        if float(np.prod(counts.astype(np.float64))) > self.occupied.shape[0]:
            # More cells in the box than occupied ones: test the occupied ones instead.
            cells = np.stack(np.unravel_index(self.occupied, tuple(self.shape)), axis=1)
            found = np.flatnonzero(np.all((cells >= first) & (cells <= last), axis=1))
        else:
            ranges = (np.arange(a, b + 1) for a, b in zip(first, last, strict=True))
            grids = np.meshgrid(*ranges, indexing="ij")
            wanted = self._keys(np.stack([g.reshape(-1) for g in grids], axis=1))
            found = np.minimum(np.searchsorted(self.occupied, wanted), self.occupied.shape[0] - 1)
            found = found[self.occupied[found] == wanted]
        candidates = self.order[_runs(self.starts[found], self.ends[found])]
        inside = np.ones(candidates.shape[0], dtype=bool)
        for k in range(self.points.shape[1]):
            column = self.points[candidates, k]
            inside &= (column >= low[k]) & (column <= high[k])
        rows: np.ndarray = np.sort(candidates[inside], kind="stable")
        return rows

    def _cells(self, points: FloatArray) -> np.ndarray:
        with np.errstate(invalid="ignore", over="ignore"):
            cells = np.floor((points - self.low) / self.cell)
        # Coordinates far outside the grid (a box from a wild prediction) clip to one past it.
        clipped: np.ndarray = np.clip(np.nan_to_num(cells, nan=-1.0), -1, self.shape).astype(np.int64)
        return clipped

    def _keys(self, cells: np.ndarray) -> np.ndarray:
        key = np.zeros(cells.shape[0], dtype=np.int64)
        for k in range(cells.shape[1]):
            key = key * self.shape[k] + cells[:, k]
        return key


def _runs(starts: np.ndarray, ends: np.ndarray) -> np.ndarray:
    """The concatenation of the ranges [starts[i], ends[i])."""
    lengths = ends - starts
    total = int(lengths.sum())
    if total == 0:
        return np.zeros(0, dtype=np.int64)
    offsets = np.repeat(starts - np.cumsum(lengths) + lengths, lengths)
    runs: np.ndarray = offsets + np.arange(total)
    return runs
