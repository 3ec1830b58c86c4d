"""Local shape descriptors that two clouds at different scales share, for a global search.

ICP only finds the local minimum nearest its start; a crop of a scene, turned and scaled, is
found anywhere in the scene only by matching what the surfaces look like. A descriptor of the
surface around a keypoint, measured within a radius r, describes the same surface patch in two
clouds when the radii correspond (r_model = s r_data): the scale search of
:mod:`frisicp_core.global_search` tries a ladder of radius pairs.

**Descriptor** (an unoriented variant of the Fast Point Feature Histogram: Rusu, Blodow and
Beetz, "Fast Point Feature Histograms (FPFH) for 3D registration", ICRA 2009). For a keypoint p
with unit normal n_p and each support point q within r (normal n_q, d = (q - p) / |q - p|):

    |n_p . d|,  |n_q . d|,  |n_p . n_q|,  and |q - p| / r,

binned into histograms, each normalised to sum 1: the three angles with 8 bins each, and the
joint histogram of |n_p . d| against |q - p| / r (4 x 4 bins: how the surface bends away from
the tangent plane with distance, a curvature profile). Absolute values make it independent of
the normals' signs, which a cloud moved by an unknown similarity cannot orient consistently
with its partner. Then, as FPFH does, every keypoint's histogram is averaged with its
neighbours' (weighted 1/distance), which widens the context to two rings. Square roots of the
histograms (the Hellinger map) make Euclidean distance a sensible histogram distance.

Normals are the least-variance direction of the support points' k nearest support points
(Hoppe et al. 1992). Support points are the cloud on a voxel grid of r / 4, keypoints on a grid
of r / 2: the descriptor sees a fixed number of samples per radius, whatever the cloud's
density, so clouds sampled differently (a sparse map, a dense scan) describe alike.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .kdtree import NearestNeighbors
from .similarity import FloatArray
from .voxel import voxel_filter

# Support points per keypoint neighbourhood queried (a surface holds ~50 within r on an r/4 grid).
_SUPPORT_NEIGHBOURS = 64
_NORMAL_NEIGHBOURS = 16  # a surface holds ~13 support points within NORMAL_REACH
# Normals are fitted to the support points within this share of the descriptor's radius.
NORMAL_REACH = 0.5
_ANGLE_BINS = 8
_JOINT_BINS = 4
# Fewest support points in a keypoint's radius for a descriptor worth matching.
_MIN_SUPPORT = 8


@dataclass(frozen=True)
class Descriptors:
    """Keypoints of one cloud at one radius and their descriptors (rows of ``values``)."""

    radius: float
    keypoints: FloatArray  # (n, m)
    normals: FloatArray  # (n, m), unoriented
    values: FloatArray  # (n, d), Hellinger-mapped histograms


def describe(points: FloatArray, radius: float, max_keypoints: int | None = None) -> Descriptors:
    """Descriptors (module doc) of ``points`` at ``radius``. ``max_keypoints`` thins the keypoint
    grid at random (seeded) when it would hold more."""
    support = voxel_filter(points, radius / 4.0)
    tree = NearestNeighbors(support)
    normals, means = _normals_within(tree, support, NORMAL_REACH * radius)
    # Moving-least-squares-like denoising: each support point onto its neighbourhood's plane (its
    # normal stays: the plane's, fitted to the noisy points, is what the projection used).
    support = support - np.einsum("ni,ni->n", support - means, normals)[:, None] * normals
    tree = NearestNeighbors(support)
    keys = voxel_filter(support, radius / 2.0)
    if max_keypoints is not None and keys.shape[0] > max_keypoints:
        chosen = np.random.default_rng(0).choice(keys.shape[0], size=max_keypoints, replace=False)
        keys = keys[np.sort(chosen)]
    _, key_index = tree.query(keys)
    key_normals = normals[key_index]
    dist_sq, neighbours = tree.query_k(keys, _SUPPORT_NEIGHBOURS)
    inside = (dist_sq <= radius * radius) & (dist_sq > 0)
    enough = inside.sum(axis=1) >= _MIN_SUPPORT
    keys, key_normals = keys[enough], key_normals[enough]
    dist_sq, neighbours, inside = dist_sq[enough], neighbours[enough], inside[enough]
    if keys.shape[0] == 0:  # nothing with enough support at this radius
        return Descriptors(radius, keys, key_normals, np.zeros((0, 3 * _ANGLE_BINS + _JOINT_BINS**2)))
    histograms = _pair_histograms(keys, key_normals, support, normals, neighbours, dist_sq, inside, radius)
    values = _smoothed(keys, histograms, radius)
    return Descriptors(radius, keys, key_normals, np.sqrt(values))


def _normals_within(
    tree: NearestNeighbors, points: FloatArray, reach: float
) -> tuple[FloatArray, FloatArray]:
    """Unit normals of ``points``: the least-variance direction of the stored points within
    ``reach`` (at most :data:`_NORMAL_NEIGHBOURS` nearest), as in Hoppe et al. 1992."""
    dist_sq, neighbours = tree.query_k(points, _NORMAL_NEIGHBOURS)
    weight = (dist_sq <= reach * reach).astype(np.float64)
    patches = np.take(tree.points, neighbours, axis=0)
    count = np.maximum(weight.sum(axis=1), 1.0)
    mean = np.einsum("nk,nki->ni", weight, patches) / count[:, None]
    centred = (patches - mean[:, None, :]) * np.sqrt(weight)[:, :, None]
    _, vectors = np.linalg.eigh(np.einsum("nki,nkj->nij", centred, centred))
    normals: FloatArray = vectors[:, :, 0]
    return normals, mean


def _pair_histograms(
    keys: FloatArray,
    key_normals: FloatArray,
    support: FloatArray,
    normals: FloatArray,
    neighbours: np.ndarray,
    dist_sq: FloatArray,
    inside: np.ndarray,
    radius: float,
) -> FloatArray:
    """Per keypoint, the normalised histograms of its pairs' features (module doc)."""
    distance = np.sqrt(dist_sq)
    with np.errstate(invalid="ignore", divide="ignore"):
        chord = (np.take(support, neighbours, axis=0) - keys[:, None, :]) / distance[:, :, None]
    other = np.take(normals, neighbours, axis=0)
    along_key = np.abs(np.einsum("nkj,nj->nk", chord, key_normals))
    along_other = np.abs(np.einsum("nkj,nkj->nk", chord, other))
    between = np.abs(np.einsum("nkj,nj->nk", other, key_normals))
    reach = distance / radius
    weight = inside.astype(np.float64)
    blocks = [_histogram(value, weight, _ANGLE_BINS) for value in (along_key, along_other, between)]
    joint = _bin(along_key, _JOINT_BINS) * _JOINT_BINS + _bin(reach, _JOINT_BINS)
    blocks.append(_counts(joint, weight, _JOINT_BINS * _JOINT_BINS))
    return np.concatenate(blocks, axis=1)


def _bin(values: FloatArray, bins: int) -> np.ndarray:
    return np.clip(np.nan_to_num(values * bins).astype(np.int64), 0, bins - 1)


def _histogram(values: FloatArray, weight: FloatArray, bins: int) -> FloatArray:
    return _counts(_bin(values, bins), weight, bins)


def _counts(index: np.ndarray, weight: FloatArray, bins: int) -> FloatArray:
    """Normalised weighted counts of ``index`` (n, k) into ``bins`` per row."""
    rows = index.shape[0]
    flat = (np.arange(rows)[:, None] * bins + index).reshape(-1)
    counts = np.bincount(flat, weights=weight.reshape(-1), minlength=rows * bins).reshape(rows, bins)
    total = counts.sum(axis=1, keepdims=True)
    normalised: FloatArray = counts / np.maximum(total, 1e-300)
    return normalised


def _smoothed(keys: FloatArray, histograms: FloatArray, radius: float) -> FloatArray:
    """FPFH's second ring: each histogram plus the 1/distance-weighted mean of the histograms of
    the keypoints within ``radius``, renormalised per block."""
    tree = NearestNeighbors(keys)
    count = min(16, keys.shape[0])
    dist_sq, neighbours = tree.query_k(keys, count)
    distance = np.sqrt(dist_sq)
    weight = np.where((distance > 0) & (distance <= radius), 1.0 / np.maximum(distance, 1e-300), 0.0)
    total = weight.sum(axis=1, keepdims=True)
    spread = np.einsum("nk,nkd->nd", weight, np.take(histograms, neighbours, axis=0)) / np.maximum(
        total, 1e-300
    )
    combined: FloatArray = histograms + np.where(total > 0, spread, 0.0)
    blocks = [(0, _ANGLE_BINS), (_ANGLE_BINS, 2 * _ANGLE_BINS), (2 * _ANGLE_BINS, 3 * _ANGLE_BINS)]
    blocks.append((3 * _ANGLE_BINS, combined.shape[1]))
    for start, stop in blocks:
        combined[:, start:stop] /= np.maximum(combined[:, start:stop].sum(axis=1, keepdims=True), 1e-300)
    return combined
