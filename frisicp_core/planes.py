"""Local planes of point patches: the least-variance direction of each patch's scatter matrix.

A patch's normal is the eigenvector of its scatter matrix S = sum (p - mean)(p - mean)^T with the
smallest eigenvalue, which is the patch's squared out-of-plane spread (Hoppe et al. 1992). The
refinement's normals and the fit check's local planes need this for thousands of patches per
call, where LAPACK's ``eigh`` on 3 x 3 matrices costs more than finding the patches: in 3-D the eigenvalue comes in closed form (Smith 1961, "Eigenvalues of a
symmetric 3 x 3 matrix") and its eigenvector as the largest cross product of two rows of
S - lambda I, which are orthogonal to it. Patches whose smallest eigenvalue is (nearly) double
(a line of points: every direction across it has least variance) have no such pair of rows and
go to ``eigh``, as does any other dimension.

The same patches give the surface's curvature (:func:`curvature_coefficients`: a quadric height
field fitted about each point in its tangent frame), which the refinement's residuals subtract
(:mod:`frisicp_core.refine`).

The descriptors (:mod:`frisicp_core.features`) keep ``eigh``: the global search is a chain of
discrete choices (bins, matches, random triples), and normals that differ in the 16th digit
changed a marginal case's answer (test/core/test_scene_crops.py); they stay on the solver the
search was measured with.
"""

from __future__ import annotations

import numpy as np

from .similarity import FloatArray

# Below this share of the largest cross product's possible size, S - lambda I has rank < 2.
_RANK_TWO = 1e-10


def centred_patches(points: FloatArray, neighbours: np.ndarray) -> tuple[FloatArray, FloatArray]:
    """The patches ``points[neighbours]`` ((n, k) rows -> (n, k, m)) less their means, and the means
    (n, m). ``np.take`` and an einsum sum, in place: the same numbers as fancy indexing and
    ``mean(axis=1)``, at a third of the cost on the refinement's 40-point patches."""
    patches: FloatArray = np.take(points, neighbours, axis=0)
    mean: FloatArray = np.einsum("nki->ni", patches) / neighbours.shape[1]
    patches -= mean[:, None, :]
    return mean, patches


def scatter(centred: FloatArray) -> FloatArray:
    """(n, m, m) scatter matrices of (n, k, m) centred patches (a batched matrix product: several
    times faster than the equivalent einsum)."""
    matrices: FloatArray = np.matmul(centred.transpose(0, 2, 1), centred)
    return matrices


def least_variance(matrices: FloatArray) -> tuple[FloatArray, FloatArray]:
    """The smallest eigenvalue (n,) and a unit eigenvector (n, m) of each symmetric positive
    semi-definite (n, m, m) matrix (module doc). The eigenvector's sign is arbitrary."""
    if matrices.shape[1] != 3:
        values, vectors = np.linalg.eigh(matrices)
        return values[:, 0], vectors[:, :, 0]
    a = matrices
    q = np.trace(a, axis1=1, axis2=2) / 3.0
    a00, a11, a22 = a[:, 0, 0] - q, a[:, 1, 1] - q, a[:, 2, 2] - q
    a01, a02, a12 = a[:, 0, 1], a[:, 0, 2], a[:, 1, 2]
    p = np.sqrt((a00**2 + a11**2 + a22**2 + 2.0 * (a01**2 + a02**2 + a12**2)) / 6.0)
    # det(A - qI) / (2 p^3) = cos(3 phi), written out (numpy's batched det costs more).
    det = a00 * (a11 * a22 - a12**2) - a01 * (a01 * a22 - a12 * a02) + a02 * (a01 * a12 - a11 * a02)
    with np.errstate(invalid="ignore", divide="ignore"):
        half_det = np.clip(det / (2.0 * p**3), -1.0, 1.0)
    phi = np.arccos(np.nan_to_num(half_det)) / 3.0
    smallest = np.where(p > 0, q + 2.0 * p * np.cos(phi + 2.0 * np.pi / 3.0), q)
    rows = a - smallest[:, None, None] * np.eye(3)
    crosses = np.stack(
        [
            np.cross(rows[:, 0], rows[:, 1]),
            np.cross(rows[:, 0], rows[:, 2]),
            np.cross(rows[:, 1], rows[:, 2]),
        ],
        axis=1,
    )
    sizes = np.sum(crosses**2, axis=2)
    best = np.argmax(sizes, axis=1)
    largest = sizes[np.arange(a.shape[0]), best]
    vectors = crosses[np.arange(a.shape[0]), best] / np.sqrt(np.maximum(largest, 1e-300))[:, None]
    scale = np.max(np.abs(a), axis=(1, 2))
    degenerate = ~(largest > _RANK_TWO * scale**4)
    if degenerate.any():
        values, fallback = np.linalg.eigh(a[degenerate])
        smallest[degenerate] = values[:, 0]
        vectors[degenerate] = fallback[:, :, 0]
    return smallest, vectors


def tangent_basis(normals: FloatArray) -> FloatArray:
    """(n, m - 1, m) orthonormal bases of the planes orthogonal to unit ``normals`` (n, m), a
    function of the normal alone (m = 2 or 3)."""
    m = normals.shape[1]
    if m == 2:
        basis: FloatArray = np.stack([-normals[:, 1], normals[:, 0]], axis=1)[:, None, :]
        return basis
    # The coordinate axis least aligned with the normal, crossed with it.
    axis = np.eye(3)[np.argmin(np.abs(normals), axis=1)]
    first = np.cross(normals, axis)
    first /= np.linalg.norm(first, axis=1, keepdims=True)
    return np.stack([first, np.cross(normals, first)], axis=1)


def curvature_coefficients(offsets: FloatArray, normals: FloatArray) -> FloatArray:
    """The second-order terms of the height field fitted to each patch about its origin, as the
    packed upper triangle (:func:`packed_size` entries) of a symmetric matrix S in the cloud's
    own axes.

    ``offsets`` (n, k, m) are each patch's points less its origin b, ``normals`` (n, m) the unit
    normals there. In the tangent basis E (:func:`tangent_basis`) each point has tangential
    coordinates q = E (p - b) and height z = n . (p - b); least squares over the patch fit
    z = c + g . q + q^T K q / 2 (a quadric, as in Mitra et al. 2004's second-order approximation
    of a surface's squared distance), and S = E^T K E, so that q^T K q = o^T S o for any offset
    o (its normal part drops out) and trace S = trace K. Zeros where the patch does not
    determine K, and in dimensions other than 2 and 3 (no curvature)."""
    count, k, m = offsets.shape
    if m not in (2, 3):
        return np.zeros((count, packed_size(m)))
    basis = tangent_basis(normals)
    q = np.matmul(offsets, basis.transpose(0, 2, 1))
    z = np.matmul(offsets, normals[:, :, None])[..., 0]
    columns = 3 if m == 2 else 6
    design = np.empty((count, k, columns))
    design[..., 0] = 1.0
    if m == 2:
        design[..., 1] = q[..., 0]
        design[..., 2] = 0.5 * q[..., 0] ** 2
    else:
        u, v = q[..., 0], q[..., 1]
        design[..., 1] = u
        design[..., 2] = v
        design[..., 3] = 0.5 * u * u
        design[..., 4] = u * v
        design[..., 5] = 0.5 * v * v
    normal_matrix = np.matmul(design.transpose(0, 2, 1), design)
    right = np.matmul(design.transpose(0, 2, 1), z[..., None])
    # A tiny ridge keeps a patch that does not span the quadric (a line of points) solvable;
    # its curvature then comes out near zero instead of failing.
    ridge = 1e-12 * np.trace(normal_matrix, axis1=1, axis2=2)[:, None, None] * np.eye(columns)
    solution = np.linalg.solve(normal_matrix + ridge, right)[..., 0]
    entries = np.nan_to_num(solution[:, m:], nan=0.0, posinf=0.0, neginf=0.0)
    # K as a matrix: 1 x 1 in 2-D, 2 x 2 from (K_11, K_12, K_22) in 3-D.
    curvature = entries[:, :, None] if m == 2 else entries[:, [0, 1, 1, 2]].reshape(count, 2, 2)
    matrices = np.matmul(basis.transpose(0, 2, 1), np.matmul(curvature, basis))
    rows, cols = np.triu_indices(m)
    packed: FloatArray = matrices[:, rows, cols]
    return packed


def packed_size(dim: int) -> int:
    """Entries of a symmetric dim x dim matrix's packed upper triangle (row by row)."""
    return dim * (dim + 1) // 2


def surface_heights(offsets: FloatArray, curvatures: FloatArray, noise_variance: float = 0.0) -> FloatArray:
    """The height of the fitted surface above its tangent plane where each offset lies over it:
    o^T S o / 2 for the rows of ``offsets`` (n, m), S unpacked from the rows of ``curvatures``
    (:func:`curvature_coefficients`).

    An offset between noisy points has noise in its tangential part too, of about
    ``noise_variance`` per axis, and E[q^T K q] / 2 gains trace(K) sigma^2 / 2 from it: that much
    is taken off, so noise does not pass for curvature."""
    m = offsets.shape[1]
    rows, cols = np.triu_indices(m)
    # Off-diagonal entries stand for two terms of the quadratic form.
    weights = np.where(rows == cols, 0.5, 1.0)
    products = offsets[:, rows] * offsets[:, cols]
    heights: FloatArray = (products * curvatures) @ weights
    heights -= 0.5 * noise_variance * curvatures[:, rows == cols].sum(axis=1)
    return heights
