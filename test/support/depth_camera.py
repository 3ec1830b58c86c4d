"""A depth camera's view of a room corner, its depths on disparity shells (shared by the tests of
depth steps in the core and in the stream)."""

from __future__ import annotations

import numpy as np

# A camera at the origin looking along +z (an optical frame) into a room corner 2-4 m away.
MEDIAN_DEPTH_GUESS = 3.0


def room_corner(rng: np.random.Generator, n: int = 30_000) -> np.ndarray:
    """A floor and two walls at angles to the view, in front of the camera (z in 2-4 m)."""
    u, v = rng.uniform(-1.0, 1.0, size=(2, n))
    part = rng.integers(0, 3, size=n)
    floor = np.column_stack([1.2 * u, np.full(n, 1.0), 3.0 + v])
    left = np.column_stack([-1.2 + 0.6 * (v + 1), 0.9 * u, 3.0 + 0.8 * v])
    right = np.column_stack([1.2 - 0.6 * (v + 1), 0.9 * u, 3.0 - 0.8 * v + 0.5 * (u + 1) * 0.3])
    points: np.ndarray = np.choose(part[:, None], [floor, left, right])
    return points


def quantised(
    points: np.ndarray, step: float, depth: str, rng: np.random.Generator, noise: float = 0.0
) -> np.ndarray:
    """``points`` with their depth (z, or the range) put on disparity shells ``step`` apart at
    :data:`MEDIAN_DEPTH_GUESS`, then blurred by Gaussian ``noise`` (a share of the step) along
    the ray, as :mod:`frisicp_bench.sensor` does."""
    measure = points[:, 2] if depth == "z" else np.linalg.norm(points, axis=1)
    quantum = step / MEDIAN_DEPTH_GUESS**2
    reported = 1.0 / (np.round(1.0 / measure / quantum) * quantum)
    reported = reported * (1.0 + noise * step * rng.normal(size=reported.shape) / measure)
    moved: np.ndarray = points * (reported / measure)[:, None]
    return moved
