"""Voxel-grid down-sampling of (N, m) points: one point per occupied voxel, in numpy.

A point x lies in the voxel ``floor(x / size)`` (per axis, computed in float64; voxels are
half-open, [k size, (k + 1) size)). Of every occupied voxel the *first* point in input order is
kept, and the kept points stay in input order:

- it is a measured point, not a centroid that may lie off the surface at edges and corners;
- the input order survives, so a ring-ordered lidar scan stays spatially coherent (the core's
  KD-tree queries are faster on coherent clouds, docs/nn_backends.md);
- it is deterministic (no seed) and cheaper than a centroid (no per-voxel sums).

Cost on 100,000 points (docs/node.md): about 1 ms when the bounding grid has at most
:data:`DENSE_CELLS` cells (a lookup table with one slot per cell: ``np.minimum.at`` leaves each
voxel's smallest point number); a sort of the packed cell keys (about 6 ms) for larger grids; a
stable sort of the cell coordinates (up to about 50 ms) when key times point count overflows
int64 (grids of more than ~1e13 cells: ranges of ~1e5 voxels per axis and more). A coordinate whose cell number overflows
float64 (|x / size| > 1.8e308) is kept as a voxel of its own.

:func:`voxel_centroids` is the other grid: the mean of each voxel's points instead of its first.
A depth camera reports depths on quantised shells (disparity comes in steps), so a surface seen
at an angle comes out as terraces, and two frames from nearby viewpoints fit terrace to terrace
better than surface to surface: their registration locks the terraces, a bias no resampling of
the same points reveals (README, "Depth-sensor noise"). Averaging over voxels a step or two
wide smooths the terraces out (on a 45-degree plane, two steps: a third closer to the plane); a
first point keeps them.
"""

from __future__ import annotations

import numpy as np

# Bounding grids up to this many cells use a lookup table: 16 MiB of int32, filled in ~0.5 ms.
DENSE_CELLS = 1 << 22
_INT64_KEYS = 2.0**62  # packed keys (times the point count, for the sort) must stay below this


def voxel_filter(points: np.ndarray, size: float) -> np.ndarray:
    """The first point (input order) of every occupied voxel of edge ``size``, in input order.

    ``points`` is an (N, m) array of finite values; ``size`` > 0 in the points' units.
    Returns ``points`` itself when every point has a voxel of its own.
    """
    keep = first_in_voxel(points, size)
    return points if keep.all() else points[keep]


def first_in_voxel(points: np.ndarray, size: float) -> np.ndarray:
    """(N,) mask: True for the first point (input order) of each occupied voxel."""
    cells, fits = _cells(points, size, "voxel_filter")
    n = points.shape[0]
    keep = np.ones(n, dtype=bool)
    if n < 2:
        return keep
    if not fits.all():  # cell numbers beyond float64: each such point is a voxel of its own
        inside = np.flatnonzero(fits)
        keep[inside] = _first_in_cells([column[inside] for column in cells])
        return keep
    return _first_in_cells(cells)


def voxel_centroids(points: np.ndarray, size: float, offset: float = 0.0) -> np.ndarray:
    """The mean of the points in every occupied voxel of edge ``size``, one row per voxel, in the
    input order of each voxel's first point (module doc: why a mean). ``offset``: the grid moved
    by that many voxels along every axis (cells ``floor(x / size - offset)``).

    ``points`` is an (N, m) array of finite values; ``size`` > 0 in the points' units. A mean
    may lie off the surface at edges and corners by up to about half a voxel; a voxel holding
    one point keeps it exactly. Costs a stable sort of the cells' packed keys, more than
    :func:`voxel_filter`'s lookup table."""
    cells, fits = _cells(points, size, "voxel_centroids", offset)
    n = points.shape[0]
    if n < 2:
        return np.array(points, dtype=np.float64)
    inside = np.flatnonzero(fits)  # the others (cells beyond float64) are voxels of their own
    kept = [column[inside] for column in cells]
    packed = _packed_keys(kept) if inside.size else None
    if packed is not None:  # one packed key sorts faster than a lexicographic sort of the columns
        keys, within = [packed[0]], np.argsort(packed[0], kind="stable")
    else:
        keys, within = kept, np.lexsort(kept[::-1])
    order = inside[within]
    starts = np.flatnonzero(_run_starts(within, keys))
    values = np.asarray(points, dtype=np.float64)
    sums = np.add.reduceat(values[order], starts, axis=0) if starts.size else values[:0]
    counts = np.diff(np.append(starts, order.size))
    # Both sorts are stable: each run's head is its voxel's first point.
    firsts = np.concatenate([order[starts], np.flatnonzero(~fits)])
    means = np.concatenate([sums / counts[:, None], values[~fits]])
    ordered: np.ndarray = means[np.argsort(firsts, kind="stable")]
    return ordered


def _cells(
    points: np.ndarray, size: float, caller: str, offset: float = 0.0
) -> tuple[list[np.ndarray], np.ndarray]:
    """The cell number of every point along each axis (float64 columns of integers) on the grid
    moved by ``offset`` voxels, and which points have cells within float64 (a coordinate beyond
    ``size * 1.8e308`` has none)."""
    if points.ndim != 2:
        raise ValueError(f"points must be an (N, m) array, got shape {points.shape}")
    if not (np.isfinite(size) and size > 0):
        raise ValueError(f"voxel size must be a positive finite number, got {size}")
    columns = [points[:, k] for k in range(points.shape[1])]  # (n, m) axis-0 reductions are slow
    if not all(np.isfinite(column).all() for column in columns):
        raise ValueError(f"{caller} needs finite points (drop NaN/Inf first)")
    with np.errstate(over="ignore"):
        cells = [
            np.floor(column / size - offset) if offset else np.floor(column / size) for column in columns
        ]
    fits = np.ones(points.shape[0], dtype=bool)
    for column in cells:
        fits &= np.isfinite(column)
    return cells, fits


def _first_in_cells(cells: list[np.ndarray]) -> np.ndarray:
    """Mask of the first row of each distinct cell (cells: one float64 column of integers per axis)."""
    n = cells[0].shape[0]
    if n < 2:
        return np.ones(n, dtype=bool)
    packed = _packed_keys(cells)
    if packed is None:
        return _first_by_lexsort(cells)
    key, total = packed
    if total <= DENSE_CELLS:
        return _first_by_table(key, int(total))
    if total * n < _INT64_KEYS:
        return _first_by_sort(key)
    return _heads(np.argsort(key, kind="stable"), [key])


def _packed_keys(cells: list[np.ndarray]) -> tuple[np.ndarray, float] | None:
    """One int64 number per cell of the bounding grid (row-major) for every row of ``cells``, and
    the grid's cell count; None when the grid has too many cells for int64 keys."""
    low = [float(column.min()) for column in cells]
    spans = [float(column.max()) - start + 1.0 for column, start in zip(cells, low, strict=True)]
    with np.errstate(over="ignore"):  # a grid past float64 (tiny voxels): inf, no keys
        total = float(np.prod(spans))
    if total >= _INT64_KEYS:
        return None
    weights = np.append(np.cumprod(np.array(spans[:0:-1], dtype=np.int64))[::-1], 1)
    key = np.zeros(cells[0].shape[0], dtype=np.int64)
    for column, start, weight in zip(cells, low, weights, strict=True):
        key += (column - start).astype(np.int64) * weight  # exact: every key < total < 2^62
    return key, total


def _first_by_table(key: np.ndarray, cells: int) -> np.ndarray:
    """One slot per cell of the bounding grid holds the smallest point number that falls in it."""
    n = key.shape[0]
    index_type = np.int32 if n < 2**31 else np.int64
    numbers = np.arange(n, dtype=index_type)
    owner = np.full(cells, n, dtype=index_type)
    np.minimum.at(owner, key, numbers)
    keep: np.ndarray = owner[key] == numbers
    return keep


def _first_by_sort(key: np.ndarray) -> np.ndarray:
    """Sort key * n + point number (unique, so any sort is stable): each run's head is first."""
    n = key.shape[0]
    ordered = np.sort(key * n + np.arange(n, dtype=np.int64))
    cell = ordered // n
    head = np.empty(n, dtype=bool)
    head[0] = True
    np.not_equal(cell[1:], cell[:-1], out=head[1:])
    keep = np.zeros(n, dtype=bool)
    keep[ordered[head] % n] = True
    return keep


def _first_by_lexsort(cells: list[np.ndarray]) -> np.ndarray:
    """Grids too large for a packed key: a stable lexicographic sort of the cell coordinates."""
    return _heads(np.lexsort(cells[::-1]), cells)


def _heads(order: np.ndarray, keys: list[np.ndarray]) -> np.ndarray:
    """Mask of the rows that start a run of equal keys in the *stable* sort ``order``."""
    keep = np.zeros(order.shape[0], dtype=bool)
    keep[order[_run_starts(order, keys)]] = True
    return keep


def _run_starts(order: np.ndarray, keys: list[np.ndarray]) -> np.ndarray:
    """Mask over the positions of the sort ``order``: where a run of equal keys begins."""
    head = np.zeros(order.shape[0], dtype=bool)
    head[:1] = True
    for column in keys:
        sorted_column = column[order]
        head[1:] |= sorted_column[1:] != sorted_column[:-1]
    return head
