"""The k nearest stored points of queries that move a little: a KD-tree search answered from a list.

The refinement's Gauss-Newton steps (:mod:`frisicp_core.refine`) re-pair the same sampled points
at every pose they try, and near the optimum a pose moves each point by a small fraction of the
clouds' spacing: the k nearest points there are nearly always among the nearest found at the
pose before. Molecular dynamics keeps such neighbour lists (Verlet 1967) and re-searches only
when a particle has moved too far; here the test is exact, per query:

A query q had the stored points p_1 ... p_L nearest, at distances d_1 <= ... <= d_L (L =
:data:`LISTED` > k). Moved to q' with |q' - q| = delta, the listed p_1 ... p_k lie within
d_k + delta of it, and every unlisted point at least d_L - delta away. So when
2 delta < d_L - d_k, the k nearest of q' are the k nearest of q' among the listed: their distances
are computed directly and sorted. Other queries go to the tree. The answer is the tree's, but
for the order of points at exactly equal distances. Tracking in benchmarks/big_map_node.py's
terrain (a one-off count over 60 scans), 302 of 424 searches of a polish were answered from the
lists, the others searched afresh; five neighbours of 3,000 points cost 2.0 ms by the tree and
0.4-0.7 ms from the lists (a one-off timing on a 15,000-point surface).
"""

from __future__ import annotations

import numpy as np

from .kdtree import NearestNeighbors
from .similarity import FloatArray

# Points listed per query: the k asked for plus a margin that lets the queries move.
LISTED = 8
# A relative safety margin on the exactness test, for the rounding of the distances.
_ROUNDING = 1e-9


class NeighbourLists:
    """The :data:`LISTED` nearest points of ``tree`` of a fixed set of query rows, found at
    some position of the queries (the reference), answering :meth:`query_k` at later positions
    from the lists where that is exact (module doc). A query call that has to search more than
    half of its rows again makes its positions the new reference."""

    def __init__(self, tree: NearestNeighbors) -> None:
        self.tree = tree
        self._reference: FloatArray | None = None
        self._dist_sq: FloatArray | None = None
        self._index: np.ndarray | None = None
        self._axes: list[FloatArray] = []  # the listed points' coordinates, per axis (n, LISTED)

    def query_k(self, queries: FloatArray, k: int) -> tuple[FloatArray, np.ndarray]:
        """:meth:`NearestNeighbors.query_k` of ``queries``, the same rows as every earlier call
        (moved): (squared distances, indices), both (n, k), nearest first."""
        listed = min(LISTED, self.tree.points.shape[0])
        if k >= listed:
            return self.tree.query_k(queries, k)
        if self._reference is None or self._reference.shape != queries.shape:
            return self._searched(queries, k, listed)
        assert self._dist_sq is not None and self._index is not None
        with np.errstate(invalid="ignore", over="ignore"):
            moved = np.sqrt(np.sum((queries - self._reference) ** 2, axis=1))
            reach = np.sqrt(self._dist_sq[:, listed - 1]) - np.sqrt(self._dist_sq[:, k - 1])
            exact = 2.0 * moved < reach * (1.0 - _ROUNDING)
        if np.count_nonzero(exact) < 0.5 * exact.shape[0]:
            return self._searched(queries, k, listed)
        rows = np.flatnonzero(exact)
        everywhere = rows.shape[0] == exact.shape[0]
        moved_rows = queries if everywhere else queries[rows]
        # Squared distances summed over the axes in order, as the tree sums them; one axis at a
        # time, over (rows, LISTED) planes (numpy is slow on a last axis of length 3).
        candidate_sq = np.zeros((rows.shape[0], listed))
        for axis, plane in enumerate(self._axes):
            offset = (plane if everywhere else np.take(plane, rows, axis=0)) - moved_rows[:, axis, None]
            candidate_sq += offset * offset
        nearest = np.argsort(candidate_sq, axis=1, kind="stable")[:, :k]
        candidates = self._index if everywhere else np.take(self._index, rows, axis=0)
        found_sq = np.take_along_axis(candidate_sq, nearest, axis=1)
        found = np.take_along_axis(candidates, nearest, axis=1)
        if everywhere:
            return found_sq, found
        dist_sq = np.empty((queries.shape[0], k))
        index = np.empty((queries.shape[0], k), dtype=np.int64)
        dist_sq[rows], index[rows] = found_sq, found
        others = np.flatnonzero(~exact)
        dist_sq[others], index[others] = self.tree.query_k(queries[others], k)
        return dist_sq, index

    def _searched(self, queries: FloatArray, k: int, listed: int) -> tuple[FloatArray, np.ndarray]:
        dist_sq, index = self.tree.query_k(queries, listed)
        self._reference, self._dist_sq, self._index = queries.copy(), dist_sq, index
        listed_points = np.take(self.tree.points, index, axis=0)  # one gather, then its axes
        self._axes = [np.ascontiguousarray(listed_points[..., axis]) for axis in range(queries.shape[1])]
        return dist_sq[:, :k].copy(), index[:, :k].copy()
