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
        vector: FloatArray = Rotation.from_matrix(rotation).as_rotvec()
        return vector
    skew: FloatArray = np.real(logm(rotation))
    return skew[np.triu_indices(dim, 1)]


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
