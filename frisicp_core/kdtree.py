"""Nearest-neighbour search: one KD-tree per point set and level, queried in parallel.

pykdtree (OpenMP) is used when installed; scipy's cKDTree with ``workers=-1`` is the fallback.
``benchmarks/nn_backends.py`` (results in docs/nn_backends.md) measured the alternatives on this
package's workload. nanoflann's bindings (pynanoflann, napf) answer queries, especially far-off
ones, 1.1-1.5x faster, but build 2-3x slower: ``register`` on the node's 20k clouds was
0.99-1.26x of pykdtree with them; pynanoflann has no aarch64 or Python 3.13 wheels, napf no
3.13 wheels and a single release. small_gicp's
KdTree was 0.83-1.2x, scikit-learn's about 0.35x and this cKDTree about 0.6x; faiss is brute
force and KISS-ICP's voxel hash approximate. So pykdtree stays."""

from __future__ import annotations

from typing import Any

import numpy as np

from .similarity import FloatArray

try:  # pragma: no cover - exercised by whichever backend is installed
    from pykdtree.kdtree import KDTree as _PyKDTree
except ImportError:  # pragma: no cover
    _PyKDTree = None  # type: ignore[misc,assignment]

from scipy.spatial import cKDTree

# The backend names, once: option lists (RegistrationConfig, node parameters, CLI) derive from it.
# "auto" = the first installed of the others, in this order.
BACKENDS: tuple[str, ...] = ("auto", "pykdtree", "scipy")


def available_backends() -> tuple[str, ...]:
    """The concrete backends that can run here, fastest first (what ``auto`` picks is the first)."""
    return tuple(name for name in BACKENDS[1:] if name != "pykdtree" or _PyKDTree is not None)


class NearestNeighbors:
    """A KD-tree over fixed points; ``query`` returns (squared distances, indices)."""

    def __init__(self, points: FloatArray, backend: str = "auto") -> None:
        if backend not in BACKENDS:
            raise ValueError(f"unknown nearest-neighbour backend {backend!r}; choose one of {BACKENDS}")
        if backend != "auto" and backend not in available_backends():
            raise ValueError(f"backend {backend!r} requested but it is not installed")
        self.points = np.ascontiguousarray(points, dtype=np.float64)
        self.backend = available_backends()[0] if backend == "auto" else backend
        self._spacing: float | None = None
        self._tree: Any  # pykdtree's KDTree or scipy's cKDTree; their query signatures differ
        if self.backend == "pykdtree":
            self._tree = _PyKDTree(self.points, leafsize=16)
        else:
            self._tree = cKDTree(self.points, leafsize=16, balanced_tree=False, compact_nodes=False)

    def query(self, queries: FloatArray, bound: float | None = None) -> tuple[FloatArray, np.ndarray]:
        """Nearest stored point of every query row: (squared distances, int64 indices).

        With ``bound``, a row with no stored point within that distance gets distance inf (and
        some index): the search gives up on it early, which makes a query far from every stored
        point cheap."""
        q = np.ascontiguousarray(queries, dtype=np.float64)
        within = {} if bound is None else {"distance_upper_bound": bound}
        if self.backend == "pykdtree":
            dist_sq, idx = self._tree.query(q, k=1, sqr_dists=True, **within)
            dist_sq, idx = np.asarray(dist_sq, dtype=np.float64), idx.astype(np.int64)
        else:
            dist, idx = self._tree.query(q, k=1, workers=-1, **within)
            dist_sq, idx = dist * dist, idx.astype(np.int64, copy=False)
        # A query whose squared distance to every stored point overflows float64 (a warm start
        # with scale 1e-200 throws the points 1e200 away) finds no neighbour: both libraries
        # then return an index past the end (pykdtree 2**32 - 1, scipy n) and distance inf. Any
        # stored point will do as its partner: the distance stays inf, so the pose's merit is
        # inf and the solver drops or rejects it, instead of an IndexError.
        np.minimum(idx, self.points.shape[0] - 1, out=idx)
        return dist_sq, idx

    def query_k(self, queries: FloatArray, k: int) -> tuple[FloatArray, np.ndarray]:
        """The ``k`` nearest stored points of every query row, nearest first: (squared distances,
        int64 indices), both (n, k). ``k`` is capped at the number of stored points."""
        q = np.ascontiguousarray(queries, dtype=np.float64)
        k = min(k, self.points.shape[0])
        if self.backend == "pykdtree":
            dist_sq, idx = self._tree.query(q, k=k, sqr_dists=True)
            dist_sq = np.asarray(dist_sq, dtype=np.float64).reshape(q.shape[0], k)
            idx = idx.astype(np.int64).reshape(q.shape[0], k)
        else:
            dist, idx = self._tree.query(q, k=k, workers=-1)
            dist = np.asarray(dist, dtype=np.float64).reshape(q.shape[0], k)
            dist_sq, idx = dist * dist, np.asarray(idx, dtype=np.int64).reshape(q.shape[0], k)
        np.minimum(idx, self.points.shape[0] - 1, out=idx)  # no neighbour found: see query
        return dist_sq, idx

    def spacing(self, sample: int = 256) -> float:
        """Median distance from a stored point to its nearest *other* stored point.

        Measured once, on at most ``sample`` points spread evenly over the storage order, so it
        costs a small fixed number of queries whatever the set's size; 0 for fewer than 2 points.
        """
        if self._spacing is None:
            n = self.points.shape[0]
            q = self.points[:: max(1, n // sample)]
            if n < 2:
                self._spacing = 0.0
            elif self.backend == "pykdtree":
                dist_sq, _ = self._tree.query(q, k=2, sqr_dists=True)
                self._spacing = float(np.sqrt(np.median(dist_sq[:, 1])))
            else:
                dist, _ = self._tree.query(q, k=2)
                self._spacing = float(np.median(dist[:, 1]))
        return self._spacing


def nearest(points: FloatArray, queries: FloatArray, backend: str = "auto") -> tuple[FloatArray, np.ndarray]:
    """One-off nearest neighbours of ``queries`` among ``points`` (builds a tree; see NearestNeighbors)."""
    return NearestNeighbors(points, backend).query(queries)
