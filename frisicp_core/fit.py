"""Does a pose explain the data? Residuals measured against the clouds' own noise and spacing.

Trimmed ICP keeps the pairs that fit and drops the rest, so a low RMS of the *kept* pairs says
little: a wrong pose that lays a crop's walls onto the scene's walls and drops the misplaced
furniture keeps a fine RMS. What a right pose also does is leave no *near misses*: where the two
surfaces come close, they coincide. With

- sigma_d, sigma_m the clouds' own noise: the RMS distance of a point to the plane fitted to its
  k nearest neighbours (the roughness at the sampling scale: sensor noise plus curvature), and
  the expected point-to-plane residual of a right pair e = sqrt((s sigma_d)^2 + sigma_m^2);
- a *hit*: a point whose nearest point of the other cloud is within 3 e of its local plane and
  within 3 e plus twice that cloud's point spacing of the point itself (samplings differ);
- a *near miss*: a point that is not a hit but whose nearest point is within
  :data:`NEAR_REACH` times that hit distance: the surfaces are close there but do not coincide,

a right pose has few near misses in either direction (noise tails, the boundary of the overlap,
occlusions), a wrong one many (every misplaced object, every slid wall). The shares are measured
on an evenly strided sample of each cloud (:data:`SAMPLE` points).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .kdtree import NearestNeighbors
from .planes import centred_patches, least_variance, scatter
from .similarity import FloatArray, Similarity

SAMPLE = 1500
NEIGHBOURS = 12
HIT_SIGMAS = 3.0
# A miss counts as near when its nearest point is within this many hit distances.
NEAR_REACH = 5.0


@dataclass(frozen=True)
class Side:
    """One direction's sample: how many points hit the other surface, how many nearly did."""

    hits: int
    near_misses: int
    samples: int
    noise: float  # roughness of the *other* cloud at the hits' nearest points (model units)

    @property
    def hit_share(self) -> float:
        return self.hits / self.samples if self.samples else float("nan")

    @property
    def near_share(self) -> float:
        """Near misses among the points that came close (hits and near misses)."""
        close = self.hits + self.near_misses
        return self.near_misses / close if close else float("nan")


@dataclass(frozen=True)
class Fit:
    """Forward (data points against the model) and backward (model points against the data)."""

    forward: Side
    backward: Side
    expected_residual: float  # e of the module doc, model units

    @property
    def best_near_share(self) -> float:
        """The smaller near-miss share of the two directions: the cloud that the other covers
        (a crop in its scene) meets it everywhere it comes close; the covering one meets it
        only inside the overlap, and its points just outside count as near misses."""
        return float(np.nanmin([self.forward.near_share, self.backward.near_share]))


def measure_fit(
    sim: Similarity,
    data_tree: NearestNeighbors,
    model_tree: NearestNeighbors,
    data_spacing: float,
    model_spacing: float,
) -> Fit:
    """The hits and near misses (module doc) of ``sim`` in both directions."""
    data, model = data_tree.points, model_tree.points
    forward_points = sim.apply(data[_strided(data.shape[0])])
    forward = _closest(model_tree, forward_points)
    backward_points = sim.inverse().apply(model[_strided(model.shape[0])])
    backward = _closest(data_tree, backward_points)
    model_noise = float(np.median(forward.roughness))
    data_noise = sim.scale * float(np.median(backward.roughness))
    expected = float(np.hypot(model_noise, data_noise))
    return Fit(
        forward=forward.classify(expected, model_spacing, 1.0, model_noise),
        backward=backward.classify(expected, data_spacing * sim.scale, sim.scale, data_noise),
        expected_residual=expected,
    )


def _strided(count: int) -> np.ndarray:
    return np.arange(0, count, max(1, count // SAMPLE))


@dataclass(frozen=True)
class _Closest:
    """Query points against a cloud: distance to the nearest point, to its local plane, and that
    plane's roughness (all in the cloud's units)."""

    distance: FloatArray
    to_plane: FloatArray
    roughness: FloatArray

    def classify(self, expected: float, spacing: float, unit: float, noise: float) -> Side:
        """Hits and near misses, with distances times ``unit`` into model units."""
        distance, to_plane = self.distance * unit, self.to_plane * unit
        reach = HIT_SIGMAS * expected
        hit = (to_plane <= reach) & (distance <= reach + 2.0 * spacing)
        near = ~hit & (distance <= NEAR_REACH * (reach + 2.0 * spacing))
        return Side(int(hit.sum()), int(near.sum()), int(distance.shape[0]), noise)


def _closest(tree: NearestNeighbors, queries: FloatArray) -> _Closest:
    dist_sq, neighbours = tree.query_k(queries, NEIGHBOURS)
    mean, centred = centred_patches(tree.points, neighbours)
    smallest, normal = least_variance(scatter(centred))
    to_plane = np.abs(np.einsum("ni,ni->n", queries - mean, normal))
    roughness = np.sqrt(np.maximum(smallest / neighbours.shape[1], 0.0))
    return _Closest(np.sqrt(dist_sq[:, 0]), to_plane, roughness)
