"""Sparse operators for the sparse-to-dense hierarchy (paper Step 1, Eq. 4)."""

from __future__ import annotations

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
