"""NearestNeighbors: every installed backend answers exactly as scipy's cKDTree, in the core's contract."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import cKDTree

from frisicp_core import NearestNeighbors, RegistrationConfig, nearest
from frisicp_core import kdtree as kdtree_module
from frisicp_core.kdtree import BACKENDS, available_backends

CONCRETE = [name for name in BACKENDS if name != "auto"]


def backend_or_skip(name: str) -> str:
    if name not in available_backends():
        pytest.skip(f"backend {name!r} is not installed here")
    return name


def assert_exact(points: np.ndarray, queries: np.ndarray, dist_sq: np.ndarray, idx: np.ndarray) -> None:
    """Same answer as cKDTree; an index may differ only where two stored points tie."""
    ref_dist, ref_idx = cKDTree(points).query(queries, k=1)
    np.testing.assert_allclose(dist_sq, ref_dist**2, rtol=1e-12, atol=1e-300)
    differ = idx != ref_idx
    if differ.any():
        tie = ((points[idx[differ]] - queries[differ]) ** 2).sum(axis=1)
        np.testing.assert_allclose(tie, ref_dist[differ] ** 2, rtol=1e-12, atol=1e-300)


def test_backend_names_are_defined_once():
    assert BACKENDS[0] == "auto"
    assert len(set(BACKENDS)) == len(BACKENDS)
    assert "scipy" in available_backends()  # the fallback is always there
    assert set(available_backends()) <= set(BACKENDS[1:])
    for name in BACKENDS:
        assert RegistrationConfig(backend=name).backend == name
    with pytest.raises(ValueError, match="unknown backend"):
        RegistrationConfig(backend="flann")


@pytest.mark.parametrize("backend", CONCRETE)
@pytest.mark.parametrize("dim", [2, 3])
def test_exact_against_ckdtree(backend, dim):
    backend_or_skip(backend)
    rng = np.random.default_rng(dim)
    points = rng.normal(size=(3000, dim))
    near = points[rng.integers(0, 3000, 2000)] + rng.normal(scale=1e-3, size=(2000, dim))
    far = rng.normal(scale=10.0, size=(500, dim)) + 5.0  # cold-start queries, far from the set
    queries = np.concatenate((near, far))
    tree = NearestNeighbors(points, backend)
    assert tree.backend == backend
    dist_sq, idx = tree.query(queries)
    assert dist_sq.dtype == np.float64 and idx.dtype == np.int64
    assert dist_sq.shape == idx.shape == (queries.shape[0],)
    assert_exact(points, queries, dist_sq, idx)


@pytest.mark.parametrize("backend", CONCRETE)
def test_a_bounded_query_answers_within_the_bound_and_gives_up_beyond(backend):
    backend_or_skip(backend)
    rng = np.random.default_rng(7)
    points = rng.uniform(0.0, 1.0, size=(2000, 3))
    queries = rng.uniform(-0.5, 1.5, size=(3000, 3))
    tree = NearestNeighbors(points, backend)
    exact_sq, exact_idx = tree.query(queries)
    bounded_sq, bounded_idx = tree.query(queries, bound=0.3)
    found = np.isfinite(bounded_sq)
    assert 0.2 < found.mean() < 0.9
    np.testing.assert_array_equal(found, exact_sq < 0.3**2)
    np.testing.assert_array_equal(bounded_sq[found], exact_sq[found])
    np.testing.assert_array_equal(bounded_idx[found], exact_idx[found])
    assert np.all((bounded_idx >= 0) & (bounded_idx < 2000))  # a valid row even where none is found


@pytest.mark.parametrize("backend", CONCRETE)
def test_degenerate_inputs(backend):
    backend_or_skip(backend)
    rng = np.random.default_rng(0)
    # Duplicated points: distance 0 to a copy, and whichever copy is returned holds the query.
    base = rng.normal(size=(50, 3))
    points = np.concatenate((base, base, base))
    dist_sq, idx = NearestNeighbors(points, backend).query(base)
    np.testing.assert_array_equal(dist_sq, 0.0)
    np.testing.assert_array_equal(points[idx], base)
    # All points identical.
    same = np.ones((10, 2))
    dist_sq, idx = NearestNeighbors(same, backend).query(np.array([[1.0, 1.0], [4.0, 5.0]]))
    np.testing.assert_allclose(dist_sq, [0.0, 25.0])
    assert ((idx >= 0) & (idx < 10)).all()
    # Three points; one query; queries given as float32, non-contiguous, or lists.
    three = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 2.0, 0.0]])
    tree = NearestNeighbors(three, backend)
    dist_sq, idx = tree.query(np.array([[0.9, 0.1, 0.0]]))
    np.testing.assert_allclose(dist_sq, [0.02])
    np.testing.assert_array_equal(idx, [1])
    wide = np.array([[0.1, 9.0, 1.9, 9.0, 0.0, 9.0]])[:, ::2]  # a strided view: (0.1, 1.9, 0)
    dist_sq, idx = tree.query(wide.astype(np.float32))
    np.testing.assert_array_equal(idx, [2])
    np.testing.assert_allclose(dist_sq, [0.01 + 0.01], rtol=1e-6)
    dist_sq, idx = tree.query([[0.0, 0.0, 0.5]])
    np.testing.assert_array_equal(idx, [0])
    # No queries at all.
    dist_sq, idx = tree.query(np.empty((0, 3)))
    assert dist_sq.shape == idx.shape == (0,)
    assert dist_sq.dtype == np.float64 and idx.dtype == np.int64


def test_auto_picks_the_first_installed_backend(monkeypatch):
    assert NearestNeighbors(np.eye(3), "auto").backend == available_backends()[0]
    monkeypatch.setattr(kdtree_module, "_PyKDTree", None)
    assert available_backends() == ("scipy",)
    assert NearestNeighbors(np.eye(3)).backend == "scipy"
    with pytest.raises(ValueError, match="not installed"):
        NearestNeighbors(np.eye(3), "pykdtree")


def test_unknown_backend_is_refused():
    with pytest.raises(ValueError, match="unknown nearest-neighbour backend"):
        NearestNeighbors(np.eye(3), "flann")


def test_nearest_is_a_one_off_tree():
    rng = np.random.default_rng(1)
    points, queries = rng.normal(size=(200, 2)), rng.normal(size=(30, 2))
    dist_sq, idx = nearest(points, queries)
    assert_exact(points, queries, dist_sq, idx)


def test_spatial_order_is_a_permutation_that_puts_neighbours_side_by_side():
    from frisicp_core import bumpy_surface
    from frisicp_core.sampling import needs_spatial_order, spatial_order

    points = bumpy_surface(5000)  # random storage order
    order = spatial_order(points)
    assert sorted(order.tolist()) == list(range(5000))
    ordered = points[order]
    step = np.linalg.norm(np.diff(ordered, axis=0), axis=1)
    assert np.median(step) < 0.1 * np.median(np.linalg.norm(np.diff(points, axis=0), axis=1))
    assert needs_spatial_order(points, 1.0) and not needs_spatial_order(ordered, 1.0)


def test_in_spatial_order_sorts_a_scattered_cloud_once_and_leaves_an_ordered_one_alone():
    from frisicp_core import bumpy_surface
    from frisicp_core.sampling import in_spatial_order, spatial_order

    points = bumpy_surface(5000)  # random storage order
    ordered = in_spatial_order(points, 1.0)
    np.testing.assert_array_equal(ordered, points[spatial_order(points)])
    assert in_spatial_order(ordered, 1.0) is ordered  # already in order: the same array
