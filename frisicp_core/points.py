"""Validation of point sets: every bad input ends in a ValueError that names the problem."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

from .similarity import FloatArray

# Variance ratio below which a principal direction counts as absent (rank deficiency).
_RANK_TOLERANCE = 1e-12
# A point this many times farther from the median than the typical point is an outlier (only
# looked for when the set seems degenerate, to say why).
_OUTLIER_FACTOR = 1000.0


def as_point_set(points: ArrayLike, name: str, *, drop_nonfinite: bool = False) -> FloatArray:
    """Return ``points`` as a C-contiguous (N, m) float64 array fit for registration.

    Raises ``ValueError`` for: complex numbers, not 2-D, m < 2, non-finite rows (unless
    ``drop_nonfinite``, which removes them), fewer than m + 1 points, a few far outliers that
    make the rest look degenerate, or a degenerate geometry: fewer than max(2, m - 1)
    independent directions (all points identical, or collinear), where the pose is not
    determined, or numbers that are not the points of one scene (``spread`` above
    ``MAX_SPREAD``: a wrong byte order, random bytes). The checks are the same in any
    units: they run on the points divided by a power of two (exact), so points at 1e-300 or
    1e300 are judged by their shape, not their size.
    """
    if np.iscomplexobj(points):
        raise ValueError(f"{name}: complex numbers are not coordinates (give the real points)")
    try:
        pts = np.asarray(points, dtype=np.float64)
    except (TypeError, ValueError) as err:
        raise ValueError(f"{name}: cannot be read as a numeric array ({err})") from None
    if pts.ndim != 2:
        raise ValueError(f"{name}: expected an (N, m) array of points, got shape {pts.shape}")
    n, dim = pts.shape
    if dim < 2:
        raise ValueError(f"{name}: points must have at least 2 coordinates, got {dim}")
    finite = np.isfinite(pts).all(axis=1)
    bad = int(n - np.count_nonzero(finite))
    if bad:
        if not drop_nonfinite:
            raise ValueError(
                f"{name}: {bad} of {n} points contain NaN or Inf (pass drop_nonfinite=True to drop them)"
            )
        pts = pts[finite]
        n = pts.shape[0]
    if n == 0:
        raise ValueError(f"{name}: the point set is empty" + (" after dropping NaN/Inf rows" if bad else ""))
    if n < dim + 1:
        raise ValueError(f"{name}: {n} points is too few in {dim}-D, need at least {dim + 1}")
    unit = _unit(pts)
    rank = _spanned_directions(pts / unit)
    needed = max(2, dim - 1)
    if rank < needed:
        _explain_outliers(pts / unit, unit, name, needed)
        what = (
            "all points are identical"
            if rank == 0
            else "the points are collinear"
            if rank == 1
            else (f"the points span only {rank} of {dim} dimensions")
        )
        raise ValueError(
            f"{name}: degenerate geometry, {what}; registration needs {needed} independent directions"
        )
    _check_one_scene(pts / unit, name)
    return np.ascontiguousarray(pts)


def _check_one_scene(pts: FloatArray, name: str) -> None:
    """Refuse numbers that are not the coordinates of one scene (the verdict's spread test,
    :func:`spread`), before any search: a search on them finds nothing and
    took 0.4-81 s on real clouds read in the wrong byte order (``tools/fuzz/repro.py byte-order``)."""
    value = spread(pts)
    if value == math.inf:
        raise ValueError(
            f"{name}: not the points of one scene: over half of them are one point (missing returns"
            " reported as zeros instead of NaN?)"
        )
    if not value <= MAX_SPREAD:
        raise ValueError(
            f"{name}: not the points of one scene: their RMS radius is {value:.3g} times their median"
            f" radius (at most {MAX_SPREAD:g} for real clouds; numbers spanning many orders of"
            " magnitude: wrong byte order, random bytes?)"
        )


def centroid(pts: FloatArray) -> FloatArray:
    """Mean of the rows. As a matrix product: numpy's ``mean(axis=0)`` of an (n, 3) array
    reduces along the slow axis, about 30 times slower, and this runs on every level."""
    mean: FloatArray = np.ones(pts.shape[0]) @ pts / pts.shape[0]
    return mean


def _unit(pts: FloatArray) -> float:
    """The power of two at or above the largest absolute coordinate (1 for all zeros): dividing
    by it is exact and brings every coordinate into [-1, 1], where sums of squares of up to
    1e300 points stay finite."""
    largest = float(np.max(np.abs(pts)))
    return math.ldexp(1.0, math.frexp(largest)[1]) if largest > 0 else 1.0


def _explain_outliers(pts: FloatArray, unit: float, name: str, needed: int) -> None:
    """Raise if a few far points, not the shape, make ``pts`` (in units of ``unit``) look degenerate.

    One point at 1e30 among points of size 1 leaves every other direction's variance below the
    rank tolerance: the cloud looks collinear although the rest of it is a fine surface.
    Which points are far is decided on the largest coordinate difference from the median (no
    squares: a point 1e300 away must not make the others' distances vanish below float64's
    smallest number).
    """
    centre = np.median(pts, axis=0)
    distance = np.abs(pts - centre).max(axis=1)
    typical = float(np.median(distance))
    far = distance > _OUTLIER_FACTOR * typical
    if typical == 0.0 or not far.any() or far.all():
        return
    rest = pts[~far]
    if rest.shape[0] <= pts.shape[1] or _spanned_directions(rest / _unit(rest)) < needed:
        return  # degenerate without them too: the usual message is the right one
    order = np.argsort(distance)
    farthest = math.hypot(*(pts[order[-1]] - centre)) * unit
    typical = math.hypot(*(pts[order[order.size // 2]] - centre)) * unit
    count = int(far.sum())
    which = f"one point is {farthest:.3g}" if count == 1 else f"{count} points are up to {farthest:.3g}"
    raise ValueError(
        f"{name}: {which} away from the others (typical distance from their centre {typical:.3g}):"
        f" {'an outlier' if count == 1 else 'outliers'}; remove {'it' if count == 1 else 'them'}"
        " (the other points are fine)"
    )


def _spanned_directions(pts: FloatArray) -> int:
    centred = pts - centroid(pts)
    eig = np.linalg.eigvalsh(centred.T @ centred)
    top = eig[-1]
    if not top > 0:
        return 0
    return int(np.count_nonzero(eig > top * _RANK_TOLERANCE))


def check_same_dimension(data: FloatArray, model: FloatArray) -> None:
    if data.shape[1] != model.shape[1]:
        raise ValueError(f"data has {data.shape[1]} coordinates per point but model has {model.shape[1]}")


def rms_radius(pts: FloatArray) -> float:
    """sqrt(mean ||p - centroid||^2): the set's size, used for scale guesses and tolerances."""
    centred = pts - centroid(pts)
    return float(np.sqrt(np.einsum("ij,ij->", centred, centred) / pts.shape[0]))


# A cloud whose RMS radius is more than this many times its median radius is not the points of one
# scene (see spread).
MAX_SPREAD = 1000.0
# Points that spread() looks at: a median needs no more.
_SPREAD_SAMPLE = 4096


def spread(points: FloatArray) -> float:
    """RMS radius over median radius, both about the coordinate-wise median (which, unlike the
    centroid, a few huge values cannot drag away): about 1 for the points of one scene,
    astronomically large for numbers that are not coordinates."""
    sample = points[:: max(1, points.shape[0] // _SPREAD_SAMPLE)]
    centre = np.array([np.median(sample[:, k]) for k in range(sample.shape[1])])
    offsets = sample - centre
    squared = np.einsum("ij,ij->i", offsets, offsets)
    median = float(np.sqrt(np.median(squared)))
    rms = float(np.sqrt(squared.mean()))
    return rms / median if median > 0 else math.inf
