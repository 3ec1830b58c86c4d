"""Rotations as vectors: the logarithm and exponential of SO(m) and its generators, in one place.

A rotation near R0 is written ``exp(sum_k w_k G_k) R0`` with the skew-symmetric generators G_k of
:func:`generators`; the coefficients w are the rotation's *vector*. In 3-D they are the usual
rotation vector (axis times angle, scipy's ``Rotation.as_rotvec``) and G_k = [e_k]_x, so
``G_k y = e_k x y``; in 2-D one angle with G = [[0, -1], [1, 0]]; in m > 3 dimensions one
coefficient per coordinate plane (i < j), G = E_ij - E_ji. A perturbation applied on the left
turns about the axes of the frame R maps into (for a registration, the model frame's axes, as
ROS's PoseWithCovariance expects for roll, pitch and yaw).
"""

from __future__ import annotations

from functools import cache

import numpy as np
from scipy.linalg import expm, logm
from scipy.spatial.transform import Rotation

from .similarity import FloatArray


def _takes_assume_valid() -> bool:
    """Whether this scipy's Rotation.from_matrix has ``assume_valid`` (asked by calling it: an
    older scipy's is a compiled method without an introspectable signature)."""
    try:
        Rotation.from_matrix(np.eye(3), assume_valid=True)  # type: ignore[call-arg,unused-ignore]
    except TypeError:
        return False
    return True


# scipy >= 1.17 checks every matrix given to Rotation.from_matrix for orthonormality (re-fitting
# one that is not: |R R^T - I| > 1e-12) at ~50 us a call, most of an accelerated ICP step's
# bookkeeping on small sets; ``assume_valid`` skips the check. A rotation well inside that bound
# (the solver's are orthonormal to ~1e-15) is one it takes as it is either way, so the rotation
# vector is the same to the last bit. Older scipy has no such check, nor the option.
_ASSUME_VALID = _takes_assume_valid()
_ORTHONORMAL = 1e-13


def vector_size(dim: int) -> int:
    """Number of rotation parameters in ``dim`` dimensions: m (m - 1) / 2."""
    return dim * (dim - 1) // 2


@cache
def _generators(dim: int) -> FloatArray:
    if dim == 3:
        basis = np.zeros((3, 3, 3))
        for k in range(3):
            i, j = (k + 1) % 3, (k + 2) % 3
            basis[k, j, i], basis[k, i, j] = 1.0, -1.0
        return basis
    rows, columns = np.triu_indices(dim, 1)
    basis = np.zeros((rows.size, dim, dim))
    basis[np.arange(rows.size), rows, columns] = 1.0
    basis[np.arange(rows.size), columns, rows] = -1.0
    if dim == 2:
        basis = -basis  # counter-clockwise positive: [[0, -1], [1, 0]]
    basis.setflags(write=False)
    return basis


def generators(dim: int) -> FloatArray:
    """The (r, m, m) skew-symmetric generators G_k whose coefficients are the rotation vector."""
    return _generators(dim)


def log_rotation(rotation: FloatArray) -> FloatArray:
    """The rotation vector w with ``exp(sum_k w_k G_k) = rotation`` (angle at most pi)."""
    dim = rotation.shape[0]
    if dim == 2:
        return np.array([np.arctan2(rotation[1, 0], rotation[0, 0])])
    if dim == 3:
        if _ASSUME_VALID and _orthonormal(rotation):
            vector: FloatArray = Rotation.from_matrix(rotation, assume_valid=True).as_rotvec()
        else:
            vector = Rotation.from_matrix(rotation).as_rotvec()
        return vector
    skew: FloatArray = np.real(logm(rotation))
    return skew[np.triu_indices(dim, 1)]


def _orthonormal(rotation: FloatArray) -> bool:
    """True for a 3 x 3 matrix within :data:`_ORTHONORMAL` of orthonormal with determinant > 0."""
    deviation = np.abs(rotation @ rotation.T - np.eye(3)).max()
    r = rotation
    det = (
        r[0, 0] * (r[1, 1] * r[2, 2] - r[1, 2] * r[2, 1])
        - r[0, 1] * (r[1, 0] * r[2, 2] - r[1, 2] * r[2, 0])
        + r[0, 2] * (r[1, 0] * r[2, 1] - r[1, 1] * r[2, 0])
    )
    return bool(deviation <= _ORTHONORMAL and det > 0)


def exp_rotation(vector: FloatArray, dim: int) -> FloatArray:
    """The rotation ``exp(sum_k w_k G_k)`` of a rotation vector w (inverse of :func:`log_rotation`)."""
    if dim == 2:
        c, s = np.cos(vector[0]), np.sin(vector[0])
        return np.array([[c, -s], [s, c]])
    if dim == 3:
        matrix: FloatArray = Rotation.from_rotvec(vector).as_matrix()
        return matrix
    skew = np.zeros((dim, dim))
    skew[np.triu_indices(dim, 1)] = vector
    rotation: FloatArray = expm(skew - skew.T)
    return rotation
