"""Sparse operators for the sparse-to-dense hierarchy (paper Step 1, Eq. 4)."""

from __future__ import annotations

from functools import cache

import numpy as np

from .similarity import FloatArray


def downsample(points: FloatArray, max_points: int, rng: np.random.Generator) -> FloatArray:
    """A uniformly random subset of at most ``max_points`` rows, in their original order.

    This is the paper's "interlaced sampling" made independent of the input's point order:
    the subset has the set's own density, relative to its own point count, so two sets at
    different scales are thinned alike.
    """
    n = points.shape[0]
    if n <= max_points:
        return points
    keep = np.sort(rng.choice(n, size=max_points, replace=False))
    return points[keep]


def level_sizes(n_data: int, n_model: int, levels: int, coarsest_points: int) -> list[int]:
    """Point budgets per level, coarse to fine, geometric from ``coarsest_points`` to the full sets.

    The last level is always the full sets (the paper finishes on the dense data).
    """
    largest = max(n_data, n_model)
    if levels <= 1 or largest <= coarsest_points:
        return [largest]
    ratio = (largest / coarsest_points) ** (1.0 / (levels - 1))
    sizes = [round(coarsest_points * ratio**k) for k in range(levels - 1)]
    return [*sizes, largest]


# Bits per axis of the grid that spatial_order sorts on.
_ORDER_BITS = 10
# Rows checked by needs_spatial_order, and the median step between consecutive rows (relative to
# the set's RMS radius) above which the storage order counts as scattered.
_ORDER_PROBE = 256
_SCATTERED_STEP = 0.1


def needs_spatial_order(points: FloatArray, radius: float) -> bool:
    """True when consecutive rows lie far apart (a random or shuffled order).

    Scanners store points along their scan lines, where consecutive points are neighbours; a
    random order makes KD-tree queries jump around memory. Measured on a few consecutive pairs.
    """
    n = points.shape[0]
    if n < 4 * _ORDER_PROBE or radius <= 0:
        return False
    rows = points[: _ORDER_PROBE + 1]
    steps = np.sqrt(np.einsum("ij,ij->i", rows[1:] - rows[:-1], rows[1:] - rows[:-1]))
    return bool(np.median(steps) > _SCATTERED_STEP * radius)


def in_spatial_order(points: FloatArray, radius: float) -> FloatArray:
    """``points`` in Morton order (a new array) when :func:`needs_spatial_order`, else
    ``points`` itself. Spatial order sorts to itself, so applying this twice changes nothing."""
    if not needs_spatial_order(points, radius):
        return points
    ordered: FloatArray = points[spatial_order(points)]
    return ordered


def spatial_order(points: FloatArray) -> np.ndarray:
    """The permutation that sorts points along a Z-order (Morton) curve over their bounding box.

    Neighbours in space become neighbours in memory, so successive KD-tree queries touch the
    same tree nodes: on randomly ordered clouds the queries run 1.2-1.35 times faster
    (docs/nn_backends.md). The code of a cell interleaves the bits of its coordinates, each
    spread by a lookup table; the sort is numpy's radix sort of integers.
    """
    dim = points.shape[1]
    low = np.array([points[:, k].min() for k in range(dim)])  # per column: see points.centroid
    span = max(float(points[:, k].max()) - low[k] for k in range(dim)) or 1.0
    top = (1 << _ORDER_BITS) - 1
    cells = np.minimum(((points - low) * (top / span)).astype(np.int64), top)
    spread = _spread_table(dim)
    code = np.zeros(points.shape[0], dtype=np.uint64)
    for axis in range(dim):
        code |= spread[cells[:, axis]] << np.uint64(axis)
    order: np.ndarray = np.argsort(code, kind="stable")
    return order


@cache
def _spread_table(dim: int) -> np.ndarray:
    """For every value v < 2^_ORDER_BITS, v with ``dim - 1`` zero bits put between its bits."""
    values = np.arange(1 << _ORDER_BITS, dtype=np.uint64)
    spread = np.zeros_like(values)
    for bit in range(_ORDER_BITS):
        spread |= ((values >> np.uint64(bit)) & np.uint64(1)) << np.uint64(bit * dim)
    return spread
