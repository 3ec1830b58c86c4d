"""The similarity transform x -> s R x + t in m dimensions."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class Similarity:
    """An isotropic-scale rigid transform ``T(x) = s R x + t``.

    ``scale`` s > 0, ``rotation`` R is an m x m matrix with R^T R = I and det R = +1,
    ``translation`` t has m entries. Instances are immutable; composition ``a @ b`` means
    "first b, then a": ``(a @ b)(x) = a(b(x))``.
    """

    scale: float
    rotation: FloatArray
    translation: FloatArray

    def __post_init__(self) -> None:
        rotation = np.array(self.rotation, dtype=np.float64)
        translation = np.array(self.translation, dtype=np.float64).reshape(-1)
        scale = float(self.scale)
        dim = translation.shape[0]
        if rotation.shape != (dim, dim):
            raise ValueError(f"rotation must be {dim}x{dim} to match the translation, got {rotation.shape}")
        if not (np.isfinite(scale) and scale > 0.0):
            raise ValueError(f"scale must be a finite positive number, got {scale}")
        if not (np.all(np.isfinite(rotation)) and np.all(np.isfinite(translation))):
            raise ValueError("rotation and translation must be finite")
        if not np.allclose(rotation.T @ rotation, np.eye(dim), atol=1e-6) or np.linalg.det(rotation) < 0:
            raise ValueError("rotation must be orthonormal with determinant +1")
        rotation.setflags(write=False)
        translation.setflags(write=False)
        object.__setattr__(self, "scale", scale)
        object.__setattr__(self, "rotation", rotation)
        object.__setattr__(self, "translation", translation)

    @classmethod
    def _trusted(cls, scale: float, rotation: FloatArray, translation: FloatArray) -> Similarity:
        """Construct without validation, for values a solver produced (R orthonormal by construction).

        Validation costs more than an iteration on a small level, and the inner loop builds one
        similarity per iteration.
        """
        sim = object.__new__(cls)
        rotation.setflags(write=False)
        translation.setflags(write=False)
        object.__setattr__(sim, "scale", float(scale))
        object.__setattr__(sim, "rotation", rotation)
        object.__setattr__(sim, "translation", translation)
        return sim

    @property
    def dim(self) -> int:
        return int(self.translation.shape[0])

    @classmethod
    def identity(cls, dim: int) -> Similarity:
        return cls(1.0, np.eye(dim), np.zeros(dim))

    @classmethod
    def about(
        cls, centre: ArrayLike, scale: float, rotation: ArrayLike, shift: ArrayLike | None = None
    ) -> Similarity:
        """Scale and turn about the point ``centre``, then move by ``shift``:
        x -> s R (x - c) + c + shift, i.e. t = c - s R c + shift."""
        c = np.asarray(centre, dtype=np.float64)
        rot = np.asarray(rotation, dtype=np.float64)
        translation = c - scale * rot @ c
        return cls(scale, rot, translation if shift is None else translation + np.asarray(shift))

    def apply(self, points: ArrayLike) -> FloatArray:
        """Map an (N, m) array (or one m-vector) through the transform."""
        pts = np.asarray(points, dtype=np.float64)
        mapped: FloatArray = (self.scale * pts) @ self.rotation.T + self.translation
        return mapped

    __call__ = apply

    def __matmul__(self, other: Similarity) -> Similarity:
        if not isinstance(other, Similarity):
            return NotImplemented
        return Similarity._trusted(
            self.scale * other.scale,
            self.rotation @ other.rotation,
            self.scale * self.rotation @ other.translation + self.translation,
        )

    def inverse(self) -> Similarity:
        """``T^-1(y) = R^T (y - t) / s``."""
        rt = self.rotation.T
        return Similarity._trusted(1.0 / self.scale, rt, -(rt @ self.translation) / self.scale)

    def matrix(self) -> FloatArray:
        """The (m+1) x (m+1) homogeneous matrix ``[[s R, t], [0, 1]]``."""
        out = np.eye(self.dim + 1)
        out[: self.dim, : self.dim] = self.scale * self.rotation
        out[: self.dim, self.dim] = self.translation
        return out

    @classmethod
    def from_matrix(cls, matrix: ArrayLike) -> Similarity:
        """Inverse of :meth:`matrix`; the scale is the m-th root of det(sR)."""
        mat = np.asarray(matrix, dtype=np.float64)
        dim = mat.shape[0] - 1
        if mat.shape != (dim + 1, dim + 1) or dim < 1:
            raise ValueError(f"expected a square homogeneous matrix, got shape {mat.shape}")
        linear = mat[:dim, :dim]
        det = np.linalg.det(linear)
        if not det > 0:
            raise ValueError("the linear part has det <= 0: not a proper similarity")
        scale = det ** (1.0 / dim)
        return cls(scale, linear / scale, mat[:dim, dim])

    def rotation_angle(self) -> float:
        """Angle of R in radians (the geodesic distance to the identity)."""
        return rotation_angle(self.rotation)

    # 3-D quaternions follow ROS's geometry_msgs order (x, y, z, w).
    def quaternion(self) -> FloatArray:
        """Unit quaternion (x, y, z, w) of a 3-D rotation, with w >= 0."""
        if self.dim != 3:
            raise ValueError("quaternions exist only for 3-D similarities")
        return rotation_to_quaternion(self.rotation)

    @classmethod
    def from_quaternion(cls, scale: float, quaternion: ArrayLike, translation: ArrayLike) -> Similarity:
        """Build a 3-D similarity from a quaternion (x, y, z, w); it is normalised first."""
        return cls(scale, quaternion_to_rotation(quaternion), np.asarray(translation, dtype=np.float64))


def axis_angle_rotation(axis: ArrayLike, angle: float) -> FloatArray:
    """The 3-D rotation by ``angle`` radians about ``axis`` (any length; Rodrigues' formula)."""
    k = np.asarray(axis, dtype=np.float64)
    k = k / np.linalg.norm(k)
    skew = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    rotation: FloatArray = np.eye(3) + np.sin(angle) * skew + (1.0 - np.cos(angle)) * (skew @ skew)
    return rotation


def rotation_angle(rotation: ArrayLike) -> float:
    """Geodesic angle (radians) of a rotation matrix in any dimension.

    In 2-D/3-D this is the usual angle; in higher dimensions it is the largest
    principal angle, taken from the eigenvalues e^{±iθ} of R.
    """
    rot = np.asarray(rotation, dtype=np.float64)
    if rot.shape[0] <= 3:
        cos = (np.trace(rot) - (rot.shape[0] - 2)) / 2.0
        return float(np.arccos(np.clip(cos, -1.0, 1.0)))
    return float(np.max(np.abs(np.angle(np.linalg.eigvals(rot)))))


def quaternion_to_rotation(quaternion: ArrayLike) -> FloatArray:
    q = np.asarray(quaternion, dtype=np.float64).reshape(4)
    norm = np.linalg.norm(q)
    if not np.isfinite(norm) or norm < 1e-12:
        raise ValueError(f"quaternion must be finite and non-zero, got {q}")
    x, y, z, w = q / norm
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


def rotation_to_quaternion(rotation: ArrayLike) -> FloatArray:
    """Quaternion (x, y, z, w), w >= 0, via the symmetric 4x4 eigenproblem (stable everywhere)."""
    r = np.asarray(rotation, dtype=np.float64)
    k = (
        np.array(
            [
                [r[0, 0] - r[1, 1] - r[2, 2], r[1, 0] + r[0, 1], r[2, 0] + r[0, 2], r[2, 1] - r[1, 2]],
                [r[1, 0] + r[0, 1], r[1, 1] - r[0, 0] - r[2, 2], r[2, 1] + r[1, 2], r[0, 2] - r[2, 0]],
                [r[2, 0] + r[0, 2], r[2, 1] + r[1, 2], r[2, 2] - r[0, 0] - r[1, 1], r[1, 0] - r[0, 1]],
                [r[2, 1] - r[1, 2], r[0, 2] - r[2, 0], r[1, 0] - r[0, 1], r[0, 0] + r[1, 1] + r[2, 2]],
            ]
        )
        / 3.0
    )
    _, vecs = np.linalg.eigh(k)
    q = vecs[:, -1]
    return q if q[3] >= 0 else -q
