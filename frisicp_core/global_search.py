"""Starting poses from what the surfaces look like: descriptor matches and a robust similarity.

ICP and the hypotheses of :mod:`frisicp_core.hypotheses` start where the clouds' centroids,
radii and principal axes point; a crop of a scene sits anywhere in it, at a scale its radius
does not tell, and turned any way. This stage finds such poses from local shape:

1. **A scale ladder.** The data are described at one radius r_d = :data:`DATA_RADIUS` times
   their RMS radius (:func:`frisicp_core.features.describe`); the model at r_d s_k for the
   candidate scales s_k = ratio 2^(k/2), k in :data:`SCALE_STEPS` (ratio: the clouds' RMS radius
   ratio; a crop's true scale is a few octaves from it either way). At the right rung both
   describe the same patches.
2. **Matches.** Every data keypoint's nearest model descriptor.
3. **A robust similarity** (RANSAC, Fischler and Bolles 1981): random triples of matches whose
   two triangles are similar (side ratios within :data:`TRIANGLE_AGREEMENT` of each other, a
   scale-free test that discards most wrong triples before any fit; cf. the pairwise
   invariants TEASER++ prunes with, Yang, Shi and Carlone 2020), each solved in closed form
   (:func:`frisicp_core.estimate.estimate_similarities`) and scored by the matches it brings
   within half a model radius-step of their partners.

The best few distinct poses over all rungs, ranked by the share of matches they explain, are
returned as starting poses; ICP takes them from there and the usual screening decides.
"""

from __future__ import annotations

import numpy as np

from .estimate import PairPart, estimate_similarities
from .features import Descriptors, describe
from .kdtree import NearestNeighbors
from .points import rms_radius
from .prepared import PreparedModel
from .similarity import FloatArray, Similarity

DATA_RADIUS = 0.35
SCALE_STEPS = tuple(range(-6, 7))
TRIANGLE_AGREEMENT = 1.15
SAMPLES = 10000
# Model keypoints per rung at most (a random subset beyond), and starting poses returned.
MAX_MODEL_KEYPOINTS = 4000
STARTS = 8
# Fewest keypoints worth matching.
_MIN_KEYPOINTS = 10
# Poses scored per batch (the scoring holds batch x matches x m numbers).
_BATCH = 2000


def feature_starts(data: FloatArray, model: PreparedModel, rng: np.random.Generator) -> list[Similarity]:
    """Starting poses for ``data`` onto ``model`` from descriptor matches (module doc), best first.

    The model's descriptors are the prepared model's (:meth:`PreparedModel.descriptors`): its
    radii, DATA_RADIUS times its own RMS radius times 2^(k/2), do not depend on the data, so a
    map is described once for every cold search against it."""
    data_radius = rms_radius(data)
    ratio = model.radius / data_radius
    radius = DATA_RADIUS * data_radius
    described = describe(data, radius)
    if described.keypoints.shape[0] < _MIN_KEYPOINTS:
        return []
    scored: list[tuple[float, Similarity]] = []
    for k in SCALE_STEPS:
        rung = ratio * 2.0 ** (k / 2)
        model_described = model.descriptors(DATA_RADIUS * model.radius * 2.0 ** (k / 2), MAX_MODEL_KEYPOINTS)
        if model_described.keypoints.shape[0] < _MIN_KEYPOINTS:
            continue
        for share, pose in _robust_poses(described, model_described, rung, rng):
            scored.append((share, pose))
    scored.sort(key=lambda item: -item[0])
    return [pose for _, pose in scored[:STARTS]]


def _robust_poses(
    data: Descriptors, model: Descriptors, rung: float, rng: np.random.Generator
) -> list[tuple[float, Similarity]]:
    """The best poses of one rung, with the share of the data keypoints each explains."""
    _, nearest = NearestNeighbors(model.values).query(data.values)
    source, target = data.keypoints, model.keypoints[nearest]
    count = source.shape[0]
    triples = rng.integers(count, size=(SAMPLES, 3))
    triples = triples[
        (triples[:, 0] != triples[:, 1]) & (triples[:, 1] != triples[:, 2]) & (triples[:, 0] != triples[:, 2])
    ]
    a, b = source[triples], target[triples]
    sides_a, sides_b = _sides(a), _sides(b)
    with np.errstate(invalid="ignore", divide="ignore"):
        ratios = sides_b / sides_a
        similar = ratios.max(axis=1) / ratios.min(axis=1) < TRIANGLE_AGREEMENT
        # The rung's radii matched the patches only if the triangles' scale is near the rung's.
        similar &= np.abs(np.log(ratios.mean(axis=1) / rung)) < 0.5 * np.log(2.0)
    similar &= sides_a.min(axis=1) > data.radius  # wider than a patch: a well-conditioned fit
    if not similar.any():
        return []
    a, b = a[similar], b[similar]
    poses, valid = estimate_similarities([PairPart(a, b, np.ones(a.shape[:2]))])
    reach = 0.5 * model.radius
    explained = np.zeros(len(poses))
    for start in range(0, len(poses), _BATCH):
        rows = np.arange(start, min(len(poses), start + _BATCH))
        error = np.linalg.norm(poses.take(rows).apply(source) - target[None], axis=2)
        explained[rows] = np.count_nonzero(error < reach, axis=1)
    explained[~valid] = -1
    best = np.argsort(-explained, kind="stable")[:3]
    return [(float(explained[k]) / count, poses[int(k)]) for k in best if explained[k] > 0]


def _sides(triangles: FloatArray) -> FloatArray:
    """The three side lengths of each triangle (K, 3, m) -> (K, 3)."""
    return np.stack(
        [
            np.linalg.norm(triangles[:, 0] - triangles[:, 1], axis=1),
            np.linalg.norm(triangles[:, 1] - triangles[:, 2], axis=1),
            np.linalg.norm(triangles[:, 0] - triangles[:, 2], axis=1),
        ],
        axis=1,
    )
