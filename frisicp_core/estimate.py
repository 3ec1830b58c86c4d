"""Closed-form least-squares similarity between paired points (Umeyama 1991, weighted; Horn 1987).

For weights w_i, weighted centroids ``mx, my``, centred ``X, Y`` and ``W = sum w_i``:
``C = sum w_i Y_i X_i^T / W = U S V^T``; ``D = diag(1, ..., 1, det(U V^T))`` keeps det R = +1
even when the best orthogonal fit is a reflection; ``R = U D V^T``; ``t = my - s R mx``; and

- Umeyama's scale ``s = tr(S D) / sigma_x^2`` minimises ``sum w_i ||s R x_i + t - y_i||^2``, the
  error measured in the frame of ``y``. It shrinks as the pairs get noisier (the regression
  towards zero that lets forward-only scale ICP collapse);
- Horn's symmetric scale ``s = sigma_y / sigma_x`` minimises the same sum divided by s, i.e. the
  error measured in the frame half-way between x and y (``||sqrt(s) R x + t/sqrt(s) - y/sqrt(s)||``).
  Swapping x and y gives exactly the inverse similarity, so registering A onto B and B onto A
  are one problem. R does not depend on the scale rule.

Sums are accumulated over several *parts* (the forward and the backward pairs of an ICP
iteration) and over K poses at once (hypotheses screened together), without concatenating them.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from .points import centroid
from .poses import PoseBatch
from .similarity import FloatArray, Similarity


@dataclass(frozen=True)
class PairPart:
    """Pairs x_i -> y_i for K poses: ``source``/``target`` (n, m) shared by all K or (K, n, m);
    ``weights`` (K, n), zero for pairs left out."""

    source: FloatArray
    target: FloatArray
    weights: FloatArray


def estimate_similarities(
    parts: Sequence[PairPart],
    *,
    with_scale: bool = True,
    scale_bounds: tuple[float, float] | None = None,
    symmetric: bool = False,
    origin: tuple[FloatArray, FloatArray] | None = None,
) -> tuple[PoseBatch, np.ndarray]:
    """The K weighted least-squares similarities of the union of ``parts`` (see the module doc).

    Returns the poses and a (K,) mask of the valid ones; an invalid pose (no weight, all source
    points identical, a non-positive scale) holds garbage and must not be used. ``origin`` =
    (a point near the sources, a point near the targets) is subtracted before accumulating, so
    coordinates far from 0 (map frames) lose no precision to the sums of squares.
    """
    dim = parts[0].source.shape[-1]
    ox, oy = origin if origin is not None else (np.zeros(dim), np.zeros(dim))
    # Weighted sums over all parts: W, sum w x, sum w y, sum w |x|^2, sum w |y|^2, sum w y x^T.
    sums: list[FloatArray] = []
    for part in parts:
        x = part.source - ox
        y = part.target - oy
        w = part.weights
        terms = [
            w.sum(axis=1),
            (w[:, None, :] @ x)[:, 0, :],
            (w[:, None, :] @ y)[:, 0, :],
            _weighted_sum(w, np.einsum("...i,...i->...", x, x)),
            _weighted_sum(w, np.einsum("...i,...i->...", y, y)),
            (w[:, :, None] * y).transpose(0, 2, 1) @ x,
        ]
        sums = terms if not sums else [a + b for a, b in zip(sums, terms, strict=True)]
    total, sx, sy, sxx, syy, syx = sums
    with np.errstate(invalid="ignore", divide="ignore"):
        mx = sx / total[:, None]
        my = sy / total[:, None]
        cov = syx / total[:, None, None] - my[:, :, None] * mx[:, None, :]
        var_x = sxx / total - np.einsum("ki,ki->k", mx, mx)
        var_y = syy / total - np.einsum("ki,ki->k", my, my)
    good = np.isfinite(cov).all(axis=(1, 2)) & (total > 0)
    cov = np.where(good[:, None, None], cov, 0.0)
    u, sv, vt = np.linalg.svd(cov)
    signs = np.ones((len(total), dim))
    signs[:, -1] = np.sign(np.linalg.det(u) * np.linalg.det(vt))
    signs[signs[:, -1] == 0, -1] = 1.0
    rotation = (u * signs[:, None, :]) @ vt
    with np.errstate(invalid="ignore", divide="ignore"):
        if not with_scale:
            scale = np.ones(len(total))
        elif symmetric:
            scale = np.sqrt(np.maximum(var_y, 0.0) / var_x)
        else:
            scale = (sv * signs).sum(axis=1) / var_x
    if with_scale and scale_bounds is not None:
        scale = np.clip(scale, *scale_bounds)
    valid = good & np.isfinite(scale) & (scale > 0)
    if with_scale:
        valid &= var_x > 0
    scale = np.where(valid, scale, 1.0)
    translation = (my + oy) - scale[:, None] * np.einsum("kij,kj->ki", rotation, mx + ox)
    return PoseBatch(scale, rotation, translation), valid


def _weighted_sum(weights: FloatArray, values: FloatArray) -> FloatArray:
    """sum_i w_ki v_i for shared values (n,) or v_ki for per-pose values (K, n)."""
    if values.ndim == 1:
        shared: FloatArray = weights @ values
        return shared
    per_pose: FloatArray = np.einsum("kn,kn->k", weights, values)
    return per_pose


def estimate_similarity(
    x: ArrayLike,
    y: ArrayLike,
    weights: ArrayLike | None = None,
    *,
    with_scale: bool = True,
    scale_bounds: tuple[float, float] | None = None,
    symmetric: bool = False,
) -> Similarity:
    """Solve ``min_{s,R,t} sum_i w_i ||s R x_i + t - y_i||^2`` in closed form (module doc).

    ``with_scale=False`` fixes s = 1 (rigid, Besl-McKay/Horn). ``scale_bounds=(lo, hi)`` clips the
    scale into an interval (Du et al. 2007): the objective is a convex quadratic in s for fixed R,
    so clipping the unconstrained optimum is the constrained optimum. ``symmetric=True`` uses
    Horn's symmetric scale sigma_y / sigma_x instead of Umeyama's.
    Exact (to rounding) for noise-free pairs of a rank >= m-1 configuration.
    """
    xs = np.asarray(x, dtype=np.float64)
    ys = np.asarray(y, dtype=np.float64)
    if xs.ndim != 2 or xs.shape != ys.shape:
        raise ValueError(f"x and y must be (N, m) arrays of the same shape, got {xs.shape} and {ys.shape}")
    n = xs.shape[0]
    if n == 0:
        raise ValueError("need at least one pair of points")
    if not (np.isfinite(xs).all() and np.isfinite(ys).all()):
        raise ValueError("x and y must be finite (found NaN or Inf)")
    if weights is None:
        w = np.ones(n)
    else:
        w = np.asarray(weights, dtype=np.float64).reshape(-1)
        if w.shape[0] != n or np.any(~np.isfinite(w)) or np.any(w < 0):
            raise ValueError("weights must be N finite non-negative numbers")
        if w.sum() <= 0:
            raise ValueError("weights sum to zero")
    poses, valid = estimate_similarities(
        [PairPart(xs, ys, w[None, :])],
        with_scale=with_scale,
        scale_bounds=scale_bounds,
        symmetric=symmetric,
        origin=(centroid(xs), centroid(ys)),
    )
    if not valid[0]:
        if with_scale and np.ptp(xs[w > 0], axis=0).max() == 0:
            raise ValueError("the source points are all identical: the scale is undetermined")
        raise ValueError("degenerate pairs: the estimated scale is not positive")
    return poses[0]
