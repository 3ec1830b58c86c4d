"""The dominant plane directions of a 3-D cloud: where its walls, floor and large faces point.

Each point's normal is the least-variance direction of its :data:`NEIGHBOURS` nearest (on at
most :data:`SAMPLE` points, every k-th of a cloud in spatial order). A direction (sign-free) is
dominant when at least :data:`MIN_SHARE` of the normals lie within :data:`WIDTH` of it: votes on
a Fibonacci hemisphere of :data:`_HEMISPHERE` directions, each peak refined by mean shift to the
mode of its plane's noisy normals, peaks :data:`SEPARATION` apart. A smooth object's normals
spread over the sphere (a uniform spread puts 1.5 % within 10 degrees of a direction); a wall
holds a share of its own. :mod:`frisicp_core.plane_arrangement` reads starting poses from them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .kdtree import NearestNeighbors
from .planes import centred_patches, least_variance, scatter
from .similarity import FloatArray

# Points whose normals are fitted (every k-th of a cloud in spatial order beyond this many).
SAMPLE = 10_000
NEIGHBOURS = 12
# Directions: a normal within WIDTH of one votes for it; a dominant direction holds MIN_SHARE of
# the normals (STRONG_SHARE for a scene to count as structured), peaks SEPARATION apart.
WIDTH = np.deg2rad(10.0)
MIN_SHARE = 0.04
STRONG_SHARE = 0.08
SEPARATION = np.deg2rad(25.0)
MOST_DIRECTIONS = 5
_HEMISPHERE = 1000  # voting directions
_MEAN_SHIFT_STEPS = 8


@dataclass(frozen=True)
class PlaneDirections:
    """A cloud's sampled points, their unit normals (sign arbitrary) and its dominant directions
    (rows, unit, sign arbitrary) with the share of the normals within :data:`WIDTH` of each."""

    points: FloatArray
    normals: FloatArray
    directions: FloatArray
    shares: FloatArray

    @property
    def strong(self) -> int:
        """How many directions hold :data:`STRONG_SHARE` of the normals."""
        return int(np.count_nonzero(self.shares >= STRONG_SHARE))


def plane_directions(points: FloatArray) -> PlaneDirections:
    """The dominant plane directions of a 3-D cloud (module doc)."""
    sample = points[:: max(1, -(-points.shape[0] // SAMPLE))]
    if sample.shape[0] <= NEIGHBOURS:
        empty = np.zeros((0, 3))
        return PlaneDirections(sample, np.zeros_like(sample), empty, np.zeros(0))
    _, neighbours = NearestNeighbors(sample).query_k(sample, NEIGHBOURS)
    _, centred = centred_patches(sample, neighbours)
    _, normals = least_variance(scatter(centred))
    near = np.cos(WIDTH)
    votes = np.zeros(_HEMISPHERE)
    hemisphere = _fibonacci_hemisphere(_HEMISPHERE)
    for begin in range(0, normals.shape[0], 2000):
        votes += np.count_nonzero(np.abs(normals[begin : begin + 2000] @ hemisphere.T) > near, axis=0)
    directions: list[FloatArray] = []
    shares: list[float] = []
    apart = np.cos(SEPARATION)
    for peak in np.argsort(-votes, kind="stable"):
        if votes[peak] < MIN_SHARE * normals.shape[0] or len(directions) == MOST_DIRECTIONS:
            break
        if any(abs(hemisphere[peak] @ other) > apart for other in directions):
            continue
        direction = _mean_shift(normals, hemisphere[peak], near)
        share = float(np.mean(np.abs(normals @ direction) > near))
        if share < MIN_SHARE or any(abs(direction @ other) > apart for other in directions):
            continue
        directions.append(direction)
        shares.append(share)
    return PlaneDirections(sample, normals, np.array(directions).reshape(-1, 3), np.array(shares))


def _fibonacci_hemisphere(count: int) -> FloatArray:
    """``count`` nearly evenly spread unit vectors with z >= 0 (a Fibonacci lattice)."""
    k = np.arange(count) + 0.5
    polar = np.arccos(1.0 - k / count)
    azimuth = np.pi * (1.0 + 5.0**0.5) * k
    return np.stack([np.cos(azimuth) * np.sin(polar), np.sin(azimuth) * np.sin(polar), np.cos(polar)], axis=1)


def _mean_shift(normals: FloatArray, start: FloatArray, near: float) -> FloatArray:
    """The sign-free mean direction of the normals within ``near`` (a cosine) of ``start``,
    re-centred until it stays put: the mode of a plane's noisy normals, not the vote's bin."""
    direction = start
    for _ in range(_MEAN_SHIFT_STEPS):
        dots = normals @ direction
        inside = np.abs(dots) > near
        if not inside.any():
            break
        summed = np.sign(dots[inside]) @ normals[inside]
        moved = summed / np.linalg.norm(summed)
        settled = moved @ direction > 1.0 - 1e-12
        direction = moved
        if settled:
            break
    return direction
