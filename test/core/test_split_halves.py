"""The split halves of the uncertainty (frisicp_core.refine) pair through the whole cloud's
nearest neighbours: each half's partner is exactly the one a tree of the half would find."""

import numpy as np

from frisicp_core import NearestNeighbors, Similarity, axis_angle_rotation
from frisicp_core.refine import CANDIDATES, Candidates, Half, _sample


def test_a_halfs_partner_from_the_candidates_is_its_nearest_point_in_the_half() -> None:
    rng = np.random.default_rng(5)
    data, model = rng.normal(size=(9000, 3)), rng.normal(size=(12000, 3)) * 1.5
    pose = Similarity(1.3, axis_angle_rotation([1.0, 2.0, 0.5], 0.4), [0.1, -0.2, 0.3])
    data_tree, model_tree = NearestNeighbors(data), NearestNeighbors(model)
    candidates = Candidates.at(pose, data_tree, model_tree)
    mask = rng.random(model.shape[0]) < 0.5
    rows = np.flatnonzero(mask)

    dist_sq, partner, found = Half(mask).nearest(candidates.forward)

    queries = pose.apply(data[_sample(data.shape[0], None)])
    exact_sq, exact = NearestNeighbors(model[rows]).query(queries[found])
    assert np.array_equal(partner, rows[exact])
    assert np.allclose(dist_sq, exact_sq)
    # A half misses all of a row's candidates with probability 2^-CANDIDATES (1 in 256).
    assert found.mean() > 1.0 - 4.0 / 2**CANDIDATES
