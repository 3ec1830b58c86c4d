"""Starting poses from what the surfaces look like: descriptor matches and a robust similarity.

ICP and the hypotheses of :mod:`frisicp_core.hypotheses` start where the clouds' centroids,
radii and principal axes point; a crop of a scene sits anywhere in it, at a scale its radius
does not tell, and turned any way. This stage finds such poses from local shape:

1. **A scale ladder.** The data are described at radii r_d = :data:`DATA_RADII` times their
   RMS radius (:func:`frisicp_core.features.describe`); the model at r_d s_k for the
   candidate scales s_k = ratio 2^(k/2), k in :data:`SCALE_STEPS` (ratio: the clouds' RMS radius
   ratio; a crop's true scale is a few octaves from it either way). At the right rung both
   describe the same patches.
2. **Matches.** Every data keypoint's :data:`MATCHES` nearest model descriptors.
3. **A robust similarity** (RANSAC, Fischler and Bolles 1981): random triples of matches whose
   two triangles are similar (side ratios within :data:`TRIANGLE_AGREEMENT` of each other, a
   scale-free test that discards most wrong triples before any fit; cf. the pairwise
   invariants TEASER++ prunes with, Yang, Shi and Carlone 2020), each solved in closed form
   (:func:`frisicp_core.estimate.estimate_similarities`) and scored by the matches it brings
   within half a model radius-step of their partners. At the right rung of a 10-20 % crop only
   1-3 % of the matches are right and random triples hardly ever hold three; the triples
   the matches' agreement graph ranks best (:func:`frisicp_core.compatibility.consistent_triples`:
   pairs whose lengths and normal angles agree, ranked by how many matches agree with both)
   join the random ones.

The best poses of every rung are ranked together by how much of the two clouds they make
coincide (:func:`coverage`), and the best few are returned as starting poses; ICP takes them
from there and the usual comparison on the first dense level decides.

The search is not symmetric: every keypoint of a crop has its counterpart in the scene, few of a
scene's have one in its crop. When the answer from the data's keypoints does not fit,
:func:`frisicp_core.registration.register` searches again with the clouds' roles swapped and
inverts the poses.
"""

from __future__ import annotations

import numpy as np

from .compatibility import consistent_triples
from .estimate import PairPart, estimate_similarities
from .features import Descriptors, describe
from .kdtree import NearestNeighbors
from .points import rms_radius
from .prepared import PreparedModel
from .similarity import FloatArray, Similarity

# The second radius is the first times sqrt(2), a rung apart: both meet the same model radii,
# which are described once.
DATA_RADII = (0.35, 0.35 * 2**0.5)
# Rungs half an octave apart, 3 octaves either way of the radius ratio. Quarter-octave rungs
# found a near-truth start among the first four more often on 10 % crops, but end to end
# (benchmarks/trustworthy.py, its crop, reverse-crop and sparse-map suites, 2026-12-02) succeeded
# as often (63 of 120 cases both ways), 35 % slower: not adopted.
SCALE_STEPS = tuple(range(-6, 7))
TRIANGLE_AGREEMENT = 1.15
SAMPLES = 40000
# Model descriptors matched to each data descriptor (its nearest few: the right one is often second).
MATCHES = 3
# Model keypoints per rung at most (a random subset beyond), and starting poses returned.
MAX_MODEL_KEYPOINTS = 4000
STARTS = 8
# Poses are ranked by the points they bring within this share of the model's RMS radius of the
# other cloud (see coverage), measured on about this many points of each cloud.
FIT_REACH = 0.02
_COVERAGE_SAMPLE = 500
# Fewest keypoints worth matching.
_MIN_KEYPOINTS = 10
# Poses scored per batch (the scoring holds batch x matches x m numbers).
_BATCH = 2000
# A margin on a necessary condition (_may_agree) for the rounding of the tests it anticipates.
_ROUNDING_SLACK = 1.01


def feature_starts(data: FloatArray, model: PreparedModel, rng: np.random.Generator) -> list[Similarity]:
    """Starting poses for ``data`` onto ``model`` from descriptor matches (module doc), best first.

    The model's descriptors are the prepared model's (:meth:`PreparedModel.descriptors`): its
    radii, DATA_RADII[0] times its own RMS radius times 2^(k/2), do not depend on the data, so a
    map is described once for every cold search against it."""
    data_radius = rms_radius(data)
    ratio = model.radius / data_radius
    candidates: list[Similarity] = []
    for step, share in enumerate(DATA_RADII):
        described = describe(data, share * data_radius)
        if described.keypoints.shape[0] < _MIN_KEYPOINTS:
            continue
        for k in SCALE_STEPS:
            rung = ratio * 2.0 ** (k / 2)
            # This model radius is rung k + step of the first data radius: computed from that
            # index, so both data radii meet the same cached descriptors.
            model_radius = DATA_RADII[0] * model.radius * 2.0 ** ((k + step) / 2)
            model_described = model.descriptors(model_radius, MAX_MODEL_KEYPOINTS)
            if model_described.keypoints.shape[0] < _MIN_KEYPOINTS:
                continue
            candidates += [pose for _, pose in _robust_poses(described, model_described, rung, rng)]
    if not candidates:
        return []
    shares = coverage(candidates, data, model, FIT_REACH * model.radius)
    return [candidates[k] for k in np.argsort(-shares, kind="stable")[:STARTS]]


def coverage(
    poses: list[Similarity],
    data: FloatArray,
    model: PreparedModel,
    reach: float,
    sample: int = _COVERAGE_SAMPLE,
) -> FloatArray:
    """For each pose, the share of (a sample of about ``sample``) data points it brings within
    ``reach`` of the model plus the share of model points it brings the data within ``reach``
    of: how much of the clouds it makes coincide. The rungs' own scores are not comparable
    between rungs (a coarse rung's few keypoints are matched within a wide reach, by chance
    too); this is."""
    data_sample = data[:: max(1, data.shape[0] // sample)]
    model_sample = model.points[:: max(1, len(model) // sample)]
    model_tree, data_tree = model.tree(), NearestNeighbors(data)
    # Only whether a point comes within ``reach`` counts, so the queries give up beyond it (a
    # wrong pose throws most points far off, the dearest queries); the bound is a hair wider so
    # that a distance of exactly ``reach`` is still found.
    bound = reach * (1.0 + 1e-9)
    shares = np.zeros(len(poses))
    for k, pose in enumerate(poses):
        forward, _ = model_tree.query(pose.apply(data_sample), bound)
        back_bound = bound / pose.scale if pose.scale > 0 else None
        backward, _ = data_tree.query(pose.inverse().apply(model_sample), back_bound)
        shares[k] = np.mean(forward <= reach**2) + np.mean(backward * pose.scale**2 <= reach**2)
    return shares


def _robust_poses(
    data: Descriptors, model: Descriptors, rung: float, rng: np.random.Generator
) -> list[tuple[float, Similarity]]:
    """The best poses of one rung, each refitted to all the matches it explains (Chum, Matas and
    Kittler 2003: a sample's pose is only as good as three noisy keypoints; its inliers' least
    squares fit is far better), with the share of the data keypoints it explains."""
    _, nearest = NearestNeighbors(model.values).query_k(data.values, MATCHES)
    matches = nearest.shape[1]
    source = np.repeat(data.keypoints, matches, axis=0)
    target = model.keypoints[nearest.reshape(-1)]
    count = data.keypoints.shape[0]
    triples = rng.integers(source.shape[0], size=(SAMPLES, 3))
    keypoint = triples // matches  # three different data keypoints
    triples = triples[
        (keypoint[:, 0] != keypoint[:, 1])
        & (keypoint[:, 1] != keypoint[:, 2])
        & (keypoint[:, 0] != keypoint[:, 2])
    ]
    triples = triples[_may_agree(source, target, triples, rung, data.radius)]
    # Triples found through the matches' agreement graph (module compatibility): at the right rung
    # of a small crop so few matches are right that random triples hardly ever hold three.
    agreeing = consistent_triples(data, model, nearest, rung)
    triples = np.concatenate([triples, agreeing])
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
    out = []
    for k in np.argsort(-explained, kind="stable")[:3]:
        if explained[k] <= 0:
            continue
        pose = poses[int(k)]
        for _ in range(2):  # refit to the inliers, twice (the first refit gains some)
            inliers = np.linalg.norm(pose.apply(source) - target, axis=1) < reach
            if np.count_nonzero(inliers) < 4:
                break
            refit, ok = estimate_similarities([PairPart(source, target, inliers[None].astype(np.float64))])
            if not ok[0]:
                break
            pose = refit[0]
        share = np.count_nonzero(np.linalg.norm(pose.apply(source) - target, axis=1) < reach) / count
        out.append((float(share), pose))
    return out


def _may_agree(
    source: FloatArray, target: FloatArray, triples: np.ndarray, rung: float, radius: float
) -> np.ndarray:
    """Which triples can pass the tests of :func:`_robust_poses`, judged on one side each: most
    fail on it, and one side costs a third of three. The tests ask the three side ratios
    b / a to lie within TRIANGLE_AGREEMENT of each other and their mean within half an octave
    of ``rung``, so each ratio lies within TRIANGLE_AGREEMENT * sqrt(2) of it; and the data's
    sides to be longer than ``radius``. A triple outside this (widened by
    :data:`_ROUNDING_SLACK`) fails the tests; the ones kept are tested in full."""
    first_a = np.linalg.norm(source[triples[:, 0]] - source[triples[:, 1]], axis=1)
    first_b = np.linalg.norm(target[triples[:, 0]] - target[triples[:, 1]], axis=1)
    reach = TRIANGLE_AGREEMENT * 2.0**0.5 * _ROUNDING_SLACK
    with np.errstate(invalid="ignore", divide="ignore"):
        ratio = first_b / first_a
    keep: np.ndarray = (ratio > rung / reach) & (ratio < rung * reach) & (first_a > radius)
    return keep


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
