"""Nearest-neighbour search: one KD-tree per point set and level, queried in parallel.

pykdtree (OpenMP, about 2x faster than scipy's cKDTree for 1-NN on this kind of data) is used when
installed; scipy's cKDTree with ``workers=-1`` is the fallback.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .similarity import FloatArray

try:  # pragma: no cover - exercised by whichever backend is installed
    from pykdtree.kdtree import KDTree as _PyKDTree
except ImportError:  # pragma: no cover
    _PyKDTree = None  # type: ignore[misc,assignment]

from scipy.spatial import cKDTree

# The KD-tree libraries a configuration can ask for ("auto": pykdtree when installed, else scipy).
# Every list of backends (options, parameter descriptors, CLI choices) is derived from this one.
BACKENDS: tuple[str, ...] = ("auto", "pykdtree", "scipy")


class NearestNeighbors:
    """A KD-tree over fixed points; ``query`` returns (squared distances, indices)."""

    def __init__(self, points: FloatArray, backend: str = "auto") -> None:
        if backend not in BACKENDS:
            raise ValueError(f"unknown nearest-neighbour backend {backend!r}")
        if backend == "pykdtree" and _PyKDTree is None:
            raise ValueError("backend 'pykdtree' requested but pykdtree is not installed")
        self.points = np.ascontiguousarray(points, dtype=np.float64)
        self.backend = "pykdtree" if backend != "scipy" and _PyKDTree is not None else "scipy"
        self._tree: Any  # pykdtree's KDTree or scipy's cKDTree; their query signatures differ
        if self.backend == "pykdtree":
            self._tree = _PyKDTree(self.points, leafsize=16)
        else:
            self._tree = cKDTree(self.points, leafsize=16, balanced_tree=False, compact_nodes=False)

    def query(self, queries: FloatArray) -> tuple[FloatArray, np.ndarray]:
        """Nearest stored point of every query row: (squared distances, int64 indices)."""
        q = np.ascontiguousarray(queries, dtype=np.float64)
        if self.backend == "pykdtree":
            dist_sq, idx = self._tree.query(q, k=1, sqr_dists=True)
            return np.asarray(dist_sq, dtype=np.float64), idx.astype(np.int64)
        dist, idx = self._tree.query(q, k=1, workers=-1)
        return dist * dist, idx

    def spacing(self, sample: int) -> float:
        """Median distance from a stored point to its nearest *other* stored point.

        Measured on at most ``sample`` points spread evenly over the storage order, so it costs
        a small fixed number of queries whatever the set's size; 0 for fewer than 2 points.
        """
        n = self.points.shape[0]
        if n < 2:
            return 0.0
        q = self.points[:: max(1, n // sample)]
        if self.backend == "pykdtree":
            dist_sq, _ = self._tree.query(q, k=2, sqr_dists=True)
            return float(np.sqrt(np.median(dist_sq[:, 1])))
        dist, _ = self._tree.query(q, k=2)
        return float(np.median(dist[:, 1]))


def nearest(points: FloatArray, queries: FloatArray, backend: str = "auto") -> tuple[FloatArray, np.ndarray]:
    """One-off nearest neighbours of ``queries`` among ``points`` (builds a tree; see NearestNeighbors)."""
    return NearestNeighbors(points, backend).query(queries)
