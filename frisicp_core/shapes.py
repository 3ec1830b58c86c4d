"""Built-in synthetic shapes for demos and tests: no download, deterministic for a seed.

Both are free of symmetries, so the similarity between two copies is unique.
"""

from __future__ import annotations

import numpy as np

from .similarity import FloatArray


def bumpy_surface(n: int = 5000, seed: int = 0) -> FloatArray:
    """n points on a closed, bumpy, asymmetric 3-D surface of radius about 1.

    An ellipsoid (semi-axes 1.5, 1.0, 0.7) whose radius is modulated by
    ``1 + 0.25 sin(3 theta) cos(2 phi) + 0.1 cos(5 phi)``, sampled uniformly in direction.
    """
    rng = np.random.default_rng(seed)
    directions = rng.normal(size=(n, 3))
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    theta = np.arccos(np.clip(directions[:, 2], -1, 1))
    phi = np.arctan2(directions[:, 1], directions[:, 0])
    radius = 1.0 + 0.25 * np.sin(3 * theta) * np.cos(2 * phi) + 0.1 * np.cos(5 * phi + 0.3)
    points: FloatArray = directions * radius[:, None] * np.array([1.5, 1.0, 0.7])
    return points


def closed_contour(n: int = 1000) -> FloatArray:
    """n points along a closed, asymmetric 2-D curve of radius about 1 (evenly spaced in angle)."""
    angle = np.linspace(0.0, 2 * np.pi, n, endpoint=False)
    radius = 1.0 + 0.3 * np.cos(3 * angle) + 0.15 * np.sin(5 * angle + 0.4) + 0.1 * np.cos(angle)
    return np.column_stack((1.4 * radius * np.cos(angle), radius * np.sin(angle)))
