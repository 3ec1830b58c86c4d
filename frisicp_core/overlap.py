"""Which nearest-neighbour pairs enter the estimate: automatic overlap estimation per direction.

A scan registered onto a map overlaps it only partly, and differently in each direction: every
scan point lies on the map (forward overlap ~1) but the scan covers only a part of the map
(backward overlap = that part). Pairs from the uncovered part pull the scan outwards; untrimmed,
the bidirectional objective prefers a swollen scan to the true pose. So each direction keeps
only the pairs that belong to the overlap, and how many that is is estimated from the data.

**Automatic (``overlap=None``): trimmed ICP's overlap selection** (Chetverikov, Stepanov and
Krsek, "Robust Euclidean alignment of 3D point sets: the trimmed iterative closest point
algorithm", Image and Vision Computing 23, 2005). With the n squared distances of a direction
sorted, d_(1) <= ... <= d_(n), keep the k closest, k = xi n, where xi minimises

    psi(xi) = e(xi) / xi^(1 + lambda),   e(xi) = (1/k) sum_{i <= k} d_(i),   lambda = 2.

Keeping a pair costs its squared distance; the xi^-(1+lambda) term rewards explaining more of
the set. At a stationary point d_(k) = (2 + lambda) e(xi): the set is cut where the next squared
distance exceeds four times the mean of the kept ones, a knee in the sorted distances that
exists whatever the units, the noise or the overlap. Fractional ICP (Phillips, Liu and Tomasi,
3DIM 2007) minimises the same kind of objective (RMSD / f^lambda); gating at a multiple of a
robust residual scale (KISS-ICP's adaptive threshold, MAD-based M-estimators) breaks down once
outliers are the majority, as the backward pairs of a scan in a map are.

Two floors keep degenerate selections out: xi >= :data:`MIN_FRACTION`, and every pair closer
than the target set's point spacing is kept (below that distance a pair cannot be told from an
inlier; without this floor a map that contains some of the scan's own points would keep only
those exact matches and report a far too small overlap).

Why the scale cannot collapse or swell (the reason FRISICP is bidirectional): each direction's
psi only falls by keeping *more* pairs at a small error. Shrinking the data onto a piece of the
model leaves the model's other points far from the data: the backward psi must either keep
them (large e) or drop them (small xi, divided by xi^3); swelling it does the same to the
forward pairs. The truth, where each direction keeps exactly its overlap at the noise level,
is the minimum. The caller adds the two directions' psi into one merit (see ``registration``).

**Fixed (``overlap`` = xi in (0, 1]):** keep the xi n closest pairs of each direction (1 keeps
all, the paper). **Gating (``max_distance``):** then drop pairs farther than that many times
the median kept distance.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .similarity import FloatArray

# TrICP's lambda: the weight of explaining more of the set against the error of the kept pairs.
TRIM_LAMBDA = 2.0
# Smallest share of a direction's pairs that can be kept: an estimate resting on fewer points
# than this cannot be told from a coincidence (a scan a few percent of its map is still kept).
MIN_FRACTION = 0.02


@dataclass(frozen=True)
class Selection:
    """The kept pairs of one direction for K poses.

    ``keep`` (K, n) marks them; ``kept`` (K,) counts them; ``sum_sq`` (K,) is the sum of their
    squared distances; ``merit`` (K,) is psi of the kept pairs for the automatic overlap, else
    their mean squared distance; ``cut`` (K,) the largest kept squared distance.
    """

    keep: np.ndarray
    kept: FloatArray
    sum_sq: FloatArray
    merit: FloatArray
    cut: FloatArray

    def assign(self, rows: np.ndarray, other: Selection) -> Selection:
        """A copy with the selections of poses ``rows`` (indices) replaced by ``other``'s."""
        fields = [a.copy() for a in self._fields()]
        for mine, theirs in zip(fields, other._fields(), strict=True):
            mine[rows] = theirs
        return Selection(*fields)

    def take(self, rows: np.ndarray) -> Selection:
        """The selections of poses ``rows`` only."""
        return Selection(*(field[rows] for field in self._fields()))

    def _fields(self) -> tuple[np.ndarray, ...]:
        return (self.keep, self.kept, self.sum_sq, self.merit, self.cut)

    @property
    def fraction(self) -> FloatArray:
        """Share of the direction's pairs kept: its estimated overlap."""
        share: FloatArray = self.kept / self.keep.shape[1]
        return share


def select_pairs(
    dist_sq: FloatArray,
    floor_sq: FloatArray,
    overlap: float | None,
    max_distance: float | None,
) -> Selection:
    """Choose the pairs of one direction for K poses from their squared distances (K, n).

    ``floor_sq`` (K,) is the squared point spacing of the target set in the units of
    ``dist_sq``: pairs closer than that are always kept by the automatic selection.
    """
    n = dist_sq.shape[1]
    if overlap is None:
        keep, cut = _trimmed_overlap(dist_sq, floor_sq)
    elif overlap < 1.0:
        count = max(1, int(np.ceil(overlap * n)))
        cut = np.partition(dist_sq, count - 1, axis=1)[:, count - 1]
        keep = dist_sq <= cut[:, None]
    else:
        keep = np.ones(dist_sq.shape, dtype=bool)
        cut = np.max(dist_sq, axis=1)
    if max_distance is not None:
        limit = max_distance**2 * np.nanmedian(np.where(keep, dist_sq, np.nan), axis=1)
        keep &= dist_sq <= limit[:, None]
        cut = np.max(np.where(keep, dist_sq, 0.0), axis=1)
    kept = keep.sum(axis=1).astype(np.float64)
    sum_sq = np.where(keep, dist_sq, 0.0).sum(axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        merit = sum_sq / kept
        if overlap is None:
            merit = merit / (kept / n) ** (1.0 + TRIM_LAMBDA)
    return Selection(keep, kept, sum_sq, merit, cut)


def select_within(
    dist_sq: FloatArray, floor_sq: FloatArray, bound_sq: FloatArray
) -> tuple[Selection, np.ndarray]:
    """The automatic selection (``select_pairs`` with ``overlap=None``, no gating) from squared
    distances known only below ``bound_sq`` (K,): inf where a pair is farther (a bounded
    nearest-neighbour query). Returns the selection and, per row, whether it is the one the
    exact distances give.

    Each unknown distance is at least its row's bound, so the bound stands in for it: the
    sorted distances below the bound are the exact ones, and every partial sum beyond is at
    most the exact one, so psi there (module doc) is too. When the row's cut-off then lies below
    the bound (and so does its floor), no exact psi beyond can undercut the minimum found: the
    kept pairs, their sum and the merit are the exact ones, to the last bit (a pair that is not
    kept adds 0 either way)."""
    known = np.where(np.isfinite(dist_sq), dist_sq, bound_sq[:, None])
    selection = select_pairs(known, floor_sq, None, None)
    exact: np.ndarray = (selection.cut < bound_sq) & (floor_sq < bound_sq)
    return selection, exact


def _trimmed_overlap(dist_sq: FloatArray, floor_sq: FloatArray) -> tuple[np.ndarray, FloatArray]:
    """TrICP's psi minimisation for each row (module doc): the mask of the kept pairs and the
    largest kept squared distance."""
    rows, n = dist_sq.shape
    ordered = np.sort(dist_sq, axis=1)
    counts = np.arange(1, n + 1, dtype=np.float64)
    fractions = counts / n
    psi = (np.cumsum(ordered, axis=1) / counts) / fractions ** (1.0 + TRIM_LAMBDA)
    below_floor = (ordered <= floor_sq[:, None]).sum(axis=1)
    smallest = np.maximum(np.ceil(MIN_FRACTION * n), below_floor).clip(1, n).astype(np.int64)
    psi[counts[None, :] < smallest[:, None]] = np.inf
    best = np.argmin(psi, axis=1)
    threshold = ordered[np.arange(rows), best]
    keep: np.ndarray = dist_sq <= threshold[:, None]
    return keep, threshold
