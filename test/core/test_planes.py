"""frisicp_core.planes: the closed-form least-variance direction agrees with LAPACK's eigh."""

import numpy as np

from frisicp_core.planes import curvature_coefficients, least_variance, scatter, surface_heights


def _patches(rng: np.random.Generator, spread: tuple[float, float, float], count: int = 200) -> np.ndarray:
    """``count`` random patches of 40 points, spread per axis as given, then turned at random."""
    points = rng.normal(size=(count, 40, 3)) * np.array(spread)
    turns = np.linalg.qr(rng.normal(size=(count, 3, 3)))[0]
    return np.einsum("nij,nkj->nki", turns, points)


def _against_eigh(patches: np.ndarray) -> tuple[float, float]:
    """Largest eigenvalue error (relative to the largest eigenvalue) and largest 1 - |cos| between
    the normals of least_variance and of eigh."""
    matrices = scatter(patches - patches.mean(axis=1, keepdims=True))
    smallest, normals = least_variance(matrices)
    values, vectors = np.linalg.eigh(matrices)
    value_error = float(np.max(np.abs(smallest - values[:, 0]) / values[:, 2]))
    direction_error = float(np.max(1.0 - np.abs(np.einsum("ni,ni->n", normals, vectors[:, :, 0]))))
    return value_error, direction_error


def test_noisy_surface_patches_get_eighs_normal_and_out_of_plane_variance() -> None:
    value_error, direction_error = _against_eigh(_patches(np.random.default_rng(0), (1.0, 0.6, 0.05)))
    assert value_error < 1e-12
    assert direction_error < 1e-12


def test_a_noise_free_plane_has_zero_variance_across_it() -> None:
    value_error, direction_error = _against_eigh(_patches(np.random.default_rng(1), (1.0, 0.8, 0.0)))
    assert value_error < 1e-12
    assert direction_error < 1e-12


def test_a_line_of_points_gets_a_unit_vector_across_it() -> None:
    # Every direction across a line has least variance: the closed form's rows have rank 1 and
    # eigh answers instead; any unit vector orthogonal to the line is right.
    line = np.zeros((5, 40, 3))
    line[:, :, 0] = np.random.default_rng(2).normal(size=(5, 40))
    smallest, normals = least_variance(scatter(line - line.mean(axis=1, keepdims=True)))
    assert np.allclose(smallest, 0.0)
    assert np.allclose(np.linalg.norm(normals, axis=1), 1.0)
    assert np.allclose(normals[:, 0], 0.0)


def test_an_isotropic_or_empty_scatter_still_gives_a_unit_vector() -> None:
    matrices = np.stack([np.eye(3), np.zeros((3, 3))])
    smallest, normals = least_variance(matrices)
    assert np.allclose(smallest, [1.0, 0.0])
    assert np.allclose(np.linalg.norm(normals, axis=1), 1.0)


def test_two_dimensional_patches_use_eigh() -> None:
    patches = np.random.default_rng(3).normal(size=(50, 20, 2)) * [1.0, 0.1]
    matrices = scatter(patches - patches.mean(axis=1, keepdims=True))
    smallest, normals = least_variance(matrices)
    values, vectors = np.linalg.eigh(matrices)
    assert np.allclose(smallest, values[:, 0])
    assert np.allclose(np.abs(np.einsum("ni,ni->n", normals, vectors[:, :, 0])), 1.0)


def test_a_sphere_patch_curves_away_from_its_outward_normal_by_one_over_the_radius() -> None:
    """curvature_coefficients fits z = c + g.q + q^T K q / 2 about the patch's origin: on a sphere
    of radius 2, seen from outside, K = -I / 2 in the tangent plane, so S = -(I - n n^T) / 2 in the
    cloud's axes (packed upper triangle); surface_heights gives the sphere's drop below the
    tangent plane at a tangential offset, and nothing for an offset along the normal."""
    rng = np.random.default_rng(4)
    radius = 2.0
    directions = rng.normal(size=(3000, 3))
    points = radius * directions / np.linalg.norm(directions, axis=1, keepdims=True)
    origins = points[:5]
    normals = origins / radius  # outward
    distances = np.linalg.norm(points[None, :, :] - origins[:, None, :], axis=2)
    neighbours = np.argsort(distances, axis=1)[:, :40]
    packed = curvature_coefficients(points[neighbours] - origins[:, None, :], normals)
    expected = -(np.eye(3) - normals[:, :, None] * normals[:, None, :]) / radius
    rows, cols = np.triu_indices(3)
    np.testing.assert_allclose(packed, expected[:, rows, cols], atol=0.02)
    tangent = np.cross(normals, [0.0, 0.0, 1.0])
    tangent *= 0.1 / np.linalg.norm(tangent, axis=1, keepdims=True)
    np.testing.assert_allclose(surface_heights(tangent, packed), -(0.1**2) / (2 * radius), rtol=0.05)
    np.testing.assert_allclose(surface_heights(0.1 * normals, packed), 0.0, atol=1e-4)
