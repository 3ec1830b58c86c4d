"""Voxel-grid down-sampling: exact semantics against a plain loop, every code path, bad input."""

from __future__ import annotations

import numpy as np
import pytest

from frisicp_core import bumpy_surface, voxel
from frisicp_core.voxel import first_in_voxel, voxel_filter
from frisicp_ros.stream.outputs import rosbags_message_types
from frisicp_ros.stream.pointcloud2 import CloudError, points_to_parts, read_cloud


def reference(points: np.ndarray, size: float) -> np.ndarray:
    """The definition, one point at a time: keep a point when its voxel was not seen before."""
    seen: set[tuple[float, ...]] = set()
    keep = np.zeros(len(points), dtype=bool)
    for i, point in enumerate(points):
        with np.errstate(over="ignore"):
            cell = tuple(np.floor(point / size))
        if any(np.isinf(cell)) or cell not in seen:  # a cell beyond float64 is a voxel of its own
            keep[i] = True
            seen.add(cell)
    return keep


def test_first_point_of_each_voxel_in_input_order():
    size = 0.5  # a power of two: x / size is exact, so the boundaries below are exact too
    points = np.array(
        [
            [0.1, 0.1, 0.1],  # voxel (0, 0, 0): kept
            [0.4, 0.4, 0.4],  # same voxel: dropped
            [0.5, 0.1, 0.1],  # x on the boundary belongs to the upper voxel (1, 0, 0): kept
            [-0.1, 0.1, 0.1],  # voxel (-1, 0, 0): kept
            [0.49, 0.2, 0.3],  # voxel (0, 0, 0) again: dropped
            [0.9, 0.0, 0.0],  # voxel (1, 0, 0) again: dropped
            [0.1, 0.1, -0.5],  # voxel (0, 0, -1): kept
        ]
    )
    np.testing.assert_array_equal(first_in_voxel(points, size), [1, 0, 1, 1, 0, 0, 1])
    np.testing.assert_array_equal(voxel_filter(points, size), points[[0, 2, 3, 6]])


@pytest.mark.parametrize("dims", [2, 3])
@pytest.mark.parametrize("spread", [0.1, 3.0, 1e3, 1e7])
def test_matches_the_definition_at_every_grid_size(dims, spread):
    rng = np.random.default_rng(int(spread) + dims)
    points = rng.normal(size=(2000, dims)) * spread
    points[100:200] = points[:100] + rng.normal(scale=1e-3 * spread, size=(100, dims))  # shared voxels
    for size in (0.01 * spread, 0.3 * spread, 1e-5):
        np.testing.assert_array_equal(first_in_voxel(points, size), reference(points, size))


def test_every_code_path_gives_the_same_answer(monkeypatch):
    points = bumpy_surface(3000, seed=2)
    expected = reference(points, 0.05)
    np.testing.assert_array_equal(first_in_voxel(points, 0.05), expected)  # lookup table
    monkeypatch.setattr(voxel, "DENSE_CELLS", 0)
    np.testing.assert_array_equal(first_in_voxel(points, 0.05), expected)  # sort of packed keys
    monkeypatch.setattr(voxel, "_INT64_KEYS", 1e6)  # key * n overflows: stable argsort of keys
    np.testing.assert_array_equal(first_in_voxel(points, 0.05), expected)
    monkeypatch.setattr(voxel, "_INT64_KEYS", 1.0)  # even the key overflows: lexicographic sort
    np.testing.assert_array_equal(first_in_voxel(points, 0.05), expected)


def test_huge_coordinate_ranges():
    rng = np.random.default_rng(5)
    # 1e12 voxels per axis: far beyond any table and beyond an int64 key times the count
    points = np.vstack([rng.uniform(-1e9, 1e9, size=(500, 3)), [[1e9, 1e9, 1e9], [1e9, 1e9, 1e9]]])
    keep = first_in_voxel(points, 1e-3)
    np.testing.assert_array_equal(keep, reference(points, 1e-3))
    assert keep[:500].all() and keep[500] and not keep[501]  # the duplicate is one voxel
    # cell numbers beyond float64 (1e300 / 1e-10): each such point is a voxel of its own
    extreme = np.array([[1e300, 0.0, 0.0], [1e300, 0.0, 0.0], [0.0, 0.0, 0.0], [1e-11, 0.0, 0.0]])
    np.testing.assert_array_equal(first_in_voxel(extreme, 1e-10), [True, True, True, False])


def test_small_empty_and_invalid_input():
    assert voxel_filter(np.empty((0, 3)), 0.1).shape == (0, 3)
    one = np.array([[1.0, 2.0, 3.0]])
    assert voxel_filter(one, 0.1) is one
    with pytest.raises(ValueError, match="finite points"):
        voxel_filter(np.array([[0.0, 0.0, 0.0], [np.nan, 0.0, 0.0]]), 0.1)
    for size in (0.0, -1.0, np.nan, np.inf):
        with pytest.raises(ValueError, match="voxel size"):
            voxel_filter(one, size)
    with pytest.raises(ValueError, match=r"\(N, m\)"):
        voxel_filter(np.zeros(3), 0.1)


def cloud(points: np.ndarray) -> object:
    types = rosbags_message_types()
    return types.point_cloud(points_to_parts(points), types.header(1, "lidar"))


def test_read_cloud_applies_voxels_to_finite_points_then_the_cap():
    points = bumpy_surface(5000, seed=4)
    points[::7] = np.nan  # NaN points are dropped before the grid (organised lidar clouds)
    msg = cloud(points)
    finite = points[np.isfinite(points).all(axis=1)].astype(np.float32).astype(np.float64)
    read = read_cloud(msg, voxel_size=0.1)
    np.testing.assert_array_equal(read.points, voxel_filter(finite, 0.1))
    assert read.finite == len(finite) and read.voxels == len(read.points) < len(finite)
    capped = read_cloud(msg, max_points=300, seed=2, voxel_size=0.1)
    assert capped.points.shape == (300, 3) and capped.voxels == read.voxels
    assert {tuple(p) for p in capped.points} <= {tuple(p) for p in read.points}
    assert capped.convert_seconds > 0 and capped.downsample_seconds > 0


def test_read_cloud_averages_each_voxel_in_centroid_mode():
    points = bumpy_surface(5000, seed=5)
    points[::9] = np.nan
    msg = cloud(points)
    finite = points[np.isfinite(points).all(axis=1)].astype(np.float32).astype(np.float64)
    read = read_cloud(msg, voxel_size=0.1, voxel_mode="centroid")
    np.testing.assert_array_equal(read.points, voxel.voxel_centroids(finite, 0.1))
    # As many voxels as the first-point grid keeps, each at its points' mean instead.
    assert read.voxels == len(read.points) == len(read_cloud(msg, voxel_size=0.1).points)
    with pytest.raises(ValueError, match="voxel_mode must be one of first, centroid, got 'mean'"):
        read_cloud(msg, voxel_size=0.1, voxel_mode="mean")


def test_read_cloud_with_voxels_rejects_empty_and_all_nan_clouds():
    with pytest.raises(CloudError, match="no finite points"):
        read_cloud(cloud(np.full((10, 3), np.nan)), voxel_size=0.1)
    with pytest.raises(CloudError, match="empty cloud"):
        read_cloud(cloud(np.empty((0, 3))), voxel_size=0.1)


@pytest.mark.filterwarnings("error::RuntimeWarning")
def test_a_grid_too_fine_for_float64_keeps_every_point_without_a_warning():
    """voxel_size 1e-300 (now refused as a parameter) printed numpy's overflow warning per cloud."""
    points = np.random.default_rng(1).normal(size=(500, 3))
    assert voxel_filter(points, 1e-300) is points


def reference_centroids(points: np.ndarray, size: float) -> np.ndarray:
    """The definition, one point at a time: the mean of each voxel's points, in the order of the
    voxels' first points (a cell beyond float64 is a voxel of its own)."""
    groups: dict[object, list[int]] = {}
    for i, point in enumerate(points):
        with np.errstate(over="ignore"):
            cell = tuple(np.floor(point / size))
        groups.setdefault(("alone", i) if any(np.isinf(cell)) else cell, []).append(i)
    return np.array([points[rows].mean(axis=0) for rows in groups.values()])


def test_centroids_average_each_voxel_in_the_order_of_its_first_point():
    points = np.array(
        [
            [0.1, 0.1, 0.1],  # voxel (0, 0, 0) ...
            [0.5, 0.1, 0.1],  # voxel (1, 0, 0) ...
            [0.3, 0.3, 0.3],  # ... (0, 0, 0) again
            [0.7, 0.3, 0.1],  # ... (1, 0, 0) again
            [-0.1, 0.1, 0.1],  # voxel (-1, 0, 0): alone, kept exactly
        ]
    )
    np.testing.assert_allclose(
        voxel.voxel_centroids(points, 0.5), [[0.2, 0.2, 0.2], [0.6, 0.2, 0.1], [-0.1, 0.1, 0.1]], atol=1e-15
    )


@pytest.mark.parametrize("dims", [2, 3])
@pytest.mark.parametrize("spread", [1.0, 1e9])  # packed cell keys; a grid too big for them
def test_centroids_match_the_definition_with_cells_beyond_float64(dims, spread):
    rng = np.random.default_rng(dims)
    points = rng.normal(size=(500, dims)) * spread
    points[100:200] = points[:100] + rng.normal(scale=1e-3 * spread, size=(100, dims))
    points[7] = 1e308  # x / size overflows: its own voxel, kept as it is
    points[300] = -1e308
    got = voxel.voxel_centroids(points, 1e-3)
    np.testing.assert_allclose(got, reference_centroids(points, 1e-3), rtol=1e-12, atol=1e-12 * spread)
    for far in (1e308, -1e308):  # each kept exactly, once
        assert np.count_nonzero((got == far).all(axis=1)) == 1


def test_centroids_smooth_the_terraces_of_quantised_depth():
    """A 45-degree plane whose heights come in steps of h (uniform within a step: h / sqrt(12) off
    it): averaging over voxels two steps wide brings the points a third closer to the plane; the
    first point of each voxel keeps the steps."""
    rng = np.random.default_rng(3)
    xy = rng.uniform(0.0, 1.0, size=(20000, 2))
    step = 0.02
    terraced = np.column_stack([xy, np.round(xy[:, 0] / step) * step])

    def off_plane(cloud: np.ndarray) -> float:
        return float(np.sqrt(np.mean((cloud[:, 2] - cloud[:, 0]) ** 2))) / step

    assert 0.28 < off_plane(terraced) < 0.30
    assert off_plane(voxel.voxel_centroids(terraced, 2 * step)) < 0.21
    assert off_plane(voxel_filter(terraced, 2 * step)) > 0.27


def test_centroids_refuse_what_the_filter_refuses():
    with pytest.raises(ValueError, match="voxel_centroids needs finite points"):
        voxel.voxel_centroids(np.array([[0.0, 0.0, np.nan], [1.0, 0.0, 0.0]]), 0.1)
    with pytest.raises(ValueError, match="positive finite"):
        voxel.voxel_centroids(np.zeros((3, 3)), 0.0)
    assert voxel.voxel_centroids(np.zeros((0, 3)), 0.1).shape == (0, 3)
    np.testing.assert_array_equal(voxel.voxel_centroids(np.ones((1, 3)), 0.1), np.ones((1, 3)))
