"""Local planes of point patches: the least-variance direction of each patch's scatter matrix.

A patch's normal is the eigenvector of its scatter matrix S = sum (p - mean)(p - mean)^T with the
smallest eigenvalue, which is the patch's squared out-of-plane spread (Hoppe et al. 1992). The
refinement's normals and the fit check's local planes need this for thousands of patches per
call, where LAPACK's ``eigh`` on 3 x 3 matrices costs more than finding the patches: in 3-D the eigenvalue comes in closed form (Smith 1961, "Eigenvalues of a
symmetric 3 x 3 matrix") and its eigenvector as the largest cross product of two rows of
S - lambda I, which are orthogonal to it. Patches whose smallest eigenvalue is (nearly) double
(a line of points: every direction across it has least variance) have no such pair of rows and
go to ``eigh``, as does any other dimension.

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
