"""The split halves of the uncertainty (frisicp_core.refine) pair through the whole cloud's
nearest neighbours: each half's partner is exactly the one a tree of the half would find. Where
the verdict hangs on the sigmas they size, more splits size them."""

from typing import Any

import numpy as np

from frisicp_core import NearestNeighbors, Similarity, axis_angle_rotation, refine
from frisicp_core.refine import (
    CANDIDATES,
    MORE_SPLITS,
    SPLITS,
    Candidates,
    Half,
    ModelNormals,
    Sets,
    coincident_points,
    half_samples,
    polish,
    uncertainty_of,
)
from frisicp_core.uncertainty import SIGMAS, Uncertainty


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


class CountingNeighbors(NearestNeighbors):
    """A tree that counts the rows its k-nearest queries searched."""

    searched = 0

    def query_k(self, queries: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
        self.searched += queries.shape[0]
        return super().query_k(queries, k)


def test_a_half_moved_to_another_pose_pairs_each_row_with_its_nearest_in_the_half_there() -> None:
    """A half's later steps (refine.HALF_STEPS) are paired where the last one ended: at the new
    pose each row the half pairs gets the partner a fresh search of the whole cloud gives, for
    two moves in a row, whether its list was kept (it provably holds that partner) or searched
    again; the rows the half never pairs are left as they were."""
    rng = np.random.default_rng(8)
    data, model = rng.normal(size=(7000, 3)), rng.normal(size=(9000, 3))
    data_tree, model_tree = CountingNeighbors(data), CountingNeighbors(model)
    sets = Sets(data_tree, model_tree, data_tree.spacing(), model_tree.spacing(), ModelNormals(model_tree))
    pose = Similarity(1.1, axis_angle_rotation([0.2, 1.0, 0.3], 0.2), [0.05, 0.0, -0.1])
    candidates = Candidates.at(pose, sets.data_tree, sets.model_tree)
    half, _ = half_samples(sets, rng, candidates)
    assert half.data_half is not None and half.model_half is not None
    # Moves of a few hundredths of the spacing (0.1), then of about a third of it: most rows
    # keep their lists, the second move searches more of them again.
    poses = [
        Similarity(1.102, axis_angle_rotation([0.2, 1.0, 0.3], 0.201), [0.052, 0.0, -0.1]),
        Similarity(1.12, axis_angle_rotation([0.2, 1.0, 0.3], 0.21), [0.06, 0.01, -0.1]),
    ]
    forward_used = half.data_half.mask[candidates.data_rows]
    backward_used = half.model_half.mask[candidates.model_rows]
    assert 0.4 < forward_used.mean() < 0.6 and 0.4 < backward_used.mean() < 0.6

    used_rows = forward_used.sum() + backward_used.sum()
    moved = candidates
    for other_pose, searched_share in zip(poses, [(0.0, 0.02), (0.02, 0.2)], strict=True):
        before = moved
        data_tree.searched = model_tree.searched = 0
        moved = moved.moved(other_pose, half)
        assert searched_share[0] < (data_tree.searched + model_tree.searched) / used_rows < searched_share[1]
        fresh = Candidates.at(other_pose, sets.data_tree, sets.model_tree)

        assert moved.pose is other_pose
        for mine, theirs, old, used, other_half in (
            (moved.forward, fresh.forward, before.forward, forward_used, half.model_half),
            (moved.backward, fresh.backward, before.backward, backward_used, half.data_half),
        ):
            mine_sq, mine_partner, mine_found = other_half.nearest((mine[0][used], mine[1][used]))
            fresh_sq, fresh_partner, fresh_found = other_half.nearest((theirs[0][used], theirs[1][used]))
            assert np.array_equal(mine_found, fresh_found)
            assert np.array_equal(mine_partner, fresh_partner)
            assert np.allclose(mine_sq, fresh_sq)
            assert np.array_equal(mine[1][~used], old[1][~used])


def _noisy_surface_pair(seed: int) -> tuple[Sets, Similarity, np.ndarray]:
    """Two noisy samplings of a bumpy patch, the data moved off by a known similarity: the sets,
    that similarity's inverse (the answer) and the data's centroid."""
    rng = np.random.default_rng(seed)

    def sampled(count: int) -> np.ndarray:
        x, y = rng.uniform(-1.0, 1.0, count), rng.uniform(-1.0, 1.0, count)
        surface = np.stack([x, y, 0.3 * np.sin(2.0 * x) * np.cos(3.0 * y)], axis=1)
        return surface + rng.normal(scale=0.01, size=surface.shape)

    moved = Similarity(0.8, axis_angle_rotation([1.0, 0.0, 1.0], 0.3), [0.2, 0.1, 0.0])
    data, model = moved.apply(sampled(4000)), sampled(5000)
    return _sets(data, model), moved.inverse(), data.mean(axis=0)


def _split_uncertainty(
    sets: Sets, answer: Similarity, centroid: np.ndarray, seed: int, limits: tuple[float, float, float] | None
) -> tuple[Uncertainty, int]:
    """uncertainty_of at ``answer`` with the halves' random stream ``seed``, and how many halves
    were refined."""
    refined = 0
    original = refine._half_estimate

    def counted(*args: Any) -> Similarity | None:
        nonlocal refined
        refined += 1
        return original(*args)

    pairs = polish(answer, sets, centroid).pairs
    refine._half_estimate = counted
    try:
        result = uncertainty_of(answer, pairs, sets, centroid, np.random.default_rng(seed), limits=limits)
    finally:
        refine._half_estimate = original
    return result, refined


def test_where_the_verdict_hangs_on_the_sigmas_more_splits_size_them() -> None:
    sets, answer, centroid = _noisy_surface_pair(7)
    plain, halves = _split_uncertainty(sets, answer, centroid, 0, None)
    assert halves == 2 * SPLITS
    # Tolerances three sigmas of the scale would just meet: the verdict hangs on them.
    at_the_edge = (1e6, SIGMAS * plain.scale, 1e6)
    _, halves = _split_uncertainty(sets, answer, centroid, 0, at_the_edge)
    assert halves == 2 * (SPLITS + MORE_SPLITS)
    # Tolerances far wider than every sigma: three splits decide it as well.
    far = (1e6, 1e6, 1e6)
    _, halves = _split_uncertainty(sets, answer, centroid, 0, far)
    assert halves == 2 * SPLITS
