"""frisicp_core.neighbour_lists: queries that moved a little are answered from their lists, exactly
as the KD-tree answers them; queries that moved too far are searched again."""

import numpy as np
import pytest

from frisicp_core.kdtree import NearestNeighbors
from frisicp_core.neighbour_lists import LISTED, NeighbourLists


def _surface(rng: np.random.Generator, count: int = 6000) -> np.ndarray:
    """A noisy wavy sheet, 1 x 1 in size (spacing about 0.013)."""
    xy = rng.random((count, 2))
    z = 0.05 * np.sin(6.0 * xy[:, 0]) * np.cos(4.0 * xy[:, 1]) + rng.normal(0.0, 0.002, count)
    return np.column_stack([xy, z])


def _assert_answers_as_the_tree(lists: NeighbourLists, tree: NearestNeighbors, queries: np.ndarray) -> None:
    dist_sq, index = lists.query_k(queries, 5)
    expected_sq, expected = tree.query_k(queries, 5)
    assert np.array_equal(index, expected)
    assert np.array_equal(dist_sq, expected_sq)


@pytest.mark.parametrize("step", [0.0, 0.001, 0.004, 0.02, 0.1])
def test_moved_queries_get_the_trees_neighbours_to_the_bit(step: float) -> None:
    rng = np.random.default_rng(3)
    tree = NearestNeighbors(_surface(rng))
    queries = _surface(rng, 2000)
    lists = NeighbourLists(tree)
    _assert_answers_as_the_tree(lists, tree, queries)
    for _ in range(3):  # a few steps of a refinement, each from the last
        queries = queries + rng.normal(0.0, step, queries.shape)
        _assert_answers_as_the_tree(lists, tree, queries)


def test_small_moves_are_answered_without_searching_the_tree() -> None:
    rng = np.random.default_rng(4)
    tree = NearestNeighbors(_surface(rng))
    searched: list[int] = []
    original = tree.query_k

    def counting(queries: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
        searched.append(queries.shape[0])
        return original(queries, k)

    tree.query_k = counting  # type: ignore[method-assign]
    queries = _surface(rng, 2000)
    lists = NeighbourLists(tree)
    lists.query_k(queries, 5)
    assert searched == [2000]  # the first call lists LISTED neighbours of every query
    lists.query_k(queries + rng.normal(0.0, 1e-4, queries.shape), 5)  # a hundredth of the spacing
    # Only the queries whose 5th and LISTED-th neighbours are nearly equidistant need the tree.
    assert sum(searched[1:]) < 0.05 * 2000
    lists.query_k(queries + 0.5, 5)  # every query far from where it was listed: searched afresh
    assert searched[-1] == 2000


def test_queries_thrown_past_float64_find_what_the_tree_finds() -> None:
    rng = np.random.default_rng(5)
    tree = NearestNeighbors(_surface(rng))
    queries = _surface(rng, 500)
    lists = NeighbourLists(tree)
    lists.query_k(queries, 5)
    wild = queries.copy()
    wild[:10] = 1e300  # a few rows of a wild pose
    _assert_answers_as_the_tree(lists, tree, wild)


def test_as_many_neighbours_as_listed_or_more_go_to_the_tree() -> None:
    rng = np.random.default_rng(6)
    tree = NearestNeighbors(_surface(rng, 100))
    queries = _surface(rng, 50)
    _, index = NeighbourLists(tree).query_k(queries, LISTED + 2)
    assert index.shape == (50, LISTED + 2)
    assert np.array_equal(index, tree.query_k(queries, LISTED + 2)[1])
