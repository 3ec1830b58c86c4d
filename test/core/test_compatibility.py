"""Triples of matches through the agreement graph: found where random triples are hopeless."""

import numpy as np

from frisicp_core import Similarity, axis_angle_rotation, rotation_angle
from frisicp_core.compatibility import consistent_triples
from frisicp_core.estimate import PairPart, estimate_similarities
from frisicp_core.features import Descriptors


def unit(vectors: np.ndarray) -> np.ndarray:
    return vectors / np.linalg.norm(vectors, axis=1, keepdims=True)


def matched_keypoints(
    right: int, rng: np.random.Generator
) -> tuple[Descriptors, Descriptors, np.ndarray, Similarity]:
    """300 data keypoints, 3 matches each, onto 1,000 model keypoints at scale 2.3: only the first
    match of the first ``right`` keypoints is right (placed 5 % of a radius off, normals 3
    degrees off); the rest point at random model keypoints."""
    truth = Similarity(2.3, axis_angle_rotation(np.array([0.2, -0.5, 0.8]), 1.9), np.array([4.0, -1.0, 2.0]))
    data_points = rng.uniform(0.0, 1.0, (300, 3))
    data_normals = unit(rng.normal(size=(300, 3)))
    model_points = np.concatenate([truth.apply(data_points), rng.uniform(-3.0, 9.0, (700, 3))])
    model_normals = np.concatenate([data_normals @ truth.rotation.T, unit(rng.normal(size=(700, 3)))])
    data_radius = 0.05
    model_radius = truth.scale * data_radius
    model_points[:300] += rng.normal(scale=0.05 * model_radius, size=(300, 3))
    model_normals[:300] = unit(model_normals[:300] + rng.normal(scale=0.05, size=(300, 3)))
    nearest = rng.integers(300, 1000, size=(300, 3))
    nearest[:right, 0] = np.arange(right)
    data = Descriptors(data_radius, data_points, data_normals, np.zeros((300, 1)))
    model = Descriptors(model_radius, model_points, model_normals, np.zeros((1000, 1)))
    return data, model, nearest, truth


def test_one_percent_of_right_matches_gives_right_triples():
    """9 right matches of 900 (1 %): a random triple is all right with probability 1e-6, so
    40,000 draws find none; the graph's best triples are all right and give the pose."""
    rng = np.random.default_rng(5)
    data, model, nearest, truth = matched_keypoints(9, rng)
    triples = consistent_triples(data, model, nearest, rung=2.0)  # 13 % from the truth's scale
    right = (triples % 3 == 0) & (triples // 3 < 9)
    assert right[:20].all()
    source = data.keypoints[triples[0] // 3]
    target = model.keypoints[nearest.reshape(-1)[triples[0]]]
    poses, valid = estimate_similarities([PairPart(source[None], target[None], np.ones((1, 3)))])
    assert valid[0]
    assert np.degrees(rotation_angle(poses[0].rotation @ truth.rotation.T)) < 3.0
    assert abs(poses[0].scale / truth.scale - 1.0) < 0.05


def test_right_triples_at_a_rung_a_quarter_octave_from_the_scale():
    """Rungs lie half an octave apart, so the true scale may lie a quarter octave from the
    nearest: its right matches still agree, and come first."""
    rng = np.random.default_rng(6)
    data, model, nearest, truth = matched_keypoints(12, rng)
    for rung in (truth.scale * 2.0**-0.25, truth.scale * 2.0**0.25):
        triples = consistent_triples(data, model, nearest, rung=rung)
        right = (triples % 3 == 0) & (triples // 3 < 12)
        assert right[:20].all(), rung


def test_pairs_within_one_descriptor_radius_are_not_used():
    """Keypoints closer than the data radius make an ill-conditioned triangle: never paired."""
    rng = np.random.default_rng(7)
    data, model, nearest, _ = matched_keypoints(30, rng)
    triples = consistent_triples(data, model, nearest, rung=2.3)
    keys = data.keypoints[triples // 3]
    sides = np.linalg.norm(keys[:, [0, 1, 0]] - keys[:, [1, 2, 2]], axis=2)
    assert len(triples) > 0
    assert sides.min() > data.radius
