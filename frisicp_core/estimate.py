"""Closed-form least-squares similarity between paired points (Umeyama 1991, weighted)."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from .similarity import Similarity


def estimate_similarity(
    x: ArrayLike,
    y: ArrayLike,
    weights: ArrayLike | None = None,
    *,
    with_scale: bool = True,
    scale_bounds: tuple[float, float] | None = None,
) -> Similarity:
    """Solve ``min_{s,R,t} sum_i w_i ||s R x_i + t - y_i||^2`` in closed form.

    With weighted centroids ``mx, my``, centred ``X, Y`` and ``W = sum w_i``:
    ``C = sum w_i Y_i X_i^T / W = U S V^T``; ``D = diag(1, ..., 1, det(U V^T))`` keeps
    det R = +1 even when the best orthogonal fit is a reflection; ``R = U D V^T``;
    ``s = tr(S D) / sigma_x^2`` with ``sigma_x^2 = sum w_i ||X_i||^2 / W``; ``t = my - s R mx``.

    ``with_scale=False`` fixes s = 1 (rigid, Besl-McKay/Horn). ``scale_bounds=(lo, hi)`` clips the
    scale into an interval (Du et al. 2007): the objective is a convex quadratic in s for fixed R,
    so clipping the unconstrained optimum is the constrained optimum.
    Exact (to rounding) for noise-free pairs of a rank >= m-1 configuration.
    """
    xs = np.asarray(x, dtype=np.float64)
    ys = np.asarray(y, dtype=np.float64)
    if xs.ndim != 2 or xs.shape != ys.shape:
        raise ValueError(f"x and y must be (N, m) arrays of the same shape, got {xs.shape} and {ys.shape}")
    n, dim = xs.shape
    if n == 0:
        raise ValueError("need at least one pair of points")
    if not (np.isfinite(xs).all() and np.isfinite(ys).all()):
        raise ValueError("x and y must be finite (found NaN or Inf)")
    if weights is None:
        w = np.full(n, 1.0 / n)
    else:
        w = np.asarray(weights, dtype=np.float64).reshape(-1)
        if w.shape[0] != n or np.any(~np.isfinite(w)) or np.any(w < 0):
            raise ValueError("weights must be N finite non-negative numbers")
        total = w.sum()
        if total <= 0:
            raise ValueError("weights sum to zero")
        w = w / total
    mx = w @ xs
    my = w @ ys
    xc = xs - mx
    yc = ys - my
    cov = (yc * w[:, None]).T @ xc
    var_x = float(w @ np.einsum("ij,ij->i", xc, xc))
    u, sv, vt = np.linalg.svd(cov)
    d = np.ones(dim)
    d[-1] = np.sign(np.linalg.det(u) * np.linalg.det(vt)) or 1.0
    rotation = (u * d) @ vt
    if not with_scale:
        scale = 1.0
    else:
        if var_x <= 0:
            raise ValueError("the source points are all identical: the scale is undetermined")
        scale = float(sv @ d) / var_x
        if scale_bounds is not None:
            scale = float(np.clip(scale, *scale_bounds))
        if not scale > 0:
            raise ValueError("degenerate pairs: the estimated scale is not positive")
    translation = my - scale * rotation @ mx
    return Similarity._trusted(scale, rotation, translation)
