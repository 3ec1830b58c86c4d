"""The split halves of the uncertainty (frisicp_core.refine) pair through the whole cloud's
nearest neighbours: each half's partner is exactly the one a tree of the half would find."""

import numpy as np

from frisicp_core import NearestNeighbors, Similarity, axis_angle_rotation
from frisicp_core.refine import (
    CANDIDATES,
    Candidates,
    Half,
    ModelNormals,
    Sets,
    coincident_points,
    half_samples,
)


def test_a_halfs_partner_from_the_candidates_is_its_nearest_point_in_the_half() -> None:
    rng = np.random.default_rng(5)
    data, model = rng.normal(size=(9000, 3)), rng.normal(size=(12000, 3)) * 1.5
    pose = Similarity(1.3, axis_angle_rotation([1.0, 2.0, 0.5], 0.4), [0.1, -0.2, 0.3])
    data_tree, model_tree = NearestNeighbors(data), NearestNeighbors(model)
    candidates = Candidates.at(pose, data_tree, model_tree)
    mask = rng.random(model.shape[0]) < 0.5
    rows = np.flatnonzero(mask)

    dist_sq, partner, found = Half(mask).nearest(candidates.forward)

    queries = pose.apply(data[candidates.data_rows])
    exact_sq, exact = NearestNeighbors(model[rows]).query(queries[found])
    assert np.array_equal(partner, rows[exact])
    assert np.allclose(dist_sq, exact_sq)
    # A half misses all of a row's candidates with probability 2^-CANDIDATES (1 in 256).
    assert found.mean() > 1.0 - 4.0 / 2**CANDIDATES


def _sets(data: np.ndarray, model: np.ndarray) -> Sets:
    data_tree, model_tree = NearestNeighbors(data), NearestNeighbors(model)
    return Sets(data_tree, model_tree, data_tree.spacing(), model_tree.spacing(), ModelNormals(model_tree))


def test_a_copys_sampled_points_share_their_half_with_the_point_they_land_on() -> None:
    rng = np.random.default_rng(6)
    model = rng.normal(size=(8000, 3))
    pose = Similarity(2.0, axis_angle_rotation([0.0, 1.0, 1.0], 0.7), [1.0, 0.0, -1.0])
    sets = _sets(pose.inverse().apply(model), model)
    candidates = Candidates.at(pose, sets.data_tree, sets.model_tree)

    tied = coincident_points(pose, sets, candidates)

    assert tied is not None
    data_rows, model_rows = tied
    assert np.allclose(pose.apply(sets.data_tree.points[data_rows]), model[model_rows])
    # Every sampled row of either cloud is tied to its copy.
    assert set(candidates.data_rows) <= set(data_rows) and set(candidates.model_rows) <= set(model_rows)
    first, _ = half_samples(sets, rng, candidates, tied)
    assert first.data_half is not None and first.model_half is not None
    assert np.array_equal(first.data_half.mask[data_rows], first.model_half.mask[model_rows])


def test_two_samplings_of_one_surface_share_no_points() -> None:
    rng = np.random.default_rng(7)
    data, model = rng.normal(size=(8000, 3)), rng.normal(size=(8000, 3))
    sets = _sets(data, model)
    identity = Similarity(1.0, np.eye(3), np.zeros(3))
    assert coincident_points(identity, sets, Candidates.at(identity, sets.data_tree, sets.model_tree)) is None
