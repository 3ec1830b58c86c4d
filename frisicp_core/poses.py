"""Several similarities as arrays, so that hypotheses are iterated together in one numpy pass.

Screening initial hypotheses runs the same ICP iteration on K poses. Doing it pose by pose costs
K times the Python overhead of an iteration, which dominates on small levels; as one (K, ...)
array computation it costs about one iteration. A single pose is the case K = 1.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from .similarity import FloatArray, Similarity


@dataclass(frozen=True)
class PoseBatch:
    """K similarities ``x -> s_k R_k x + t_k``: scale (K,), rotation (K, m, m), translation (K, m)."""

    scale: FloatArray
    rotation: FloatArray
    translation: FloatArray

    @classmethod
    def of(cls, similarities: Sequence[Similarity]) -> PoseBatch:
        return cls(
            np.array([sim.scale for sim in similarities], dtype=np.float64),
            np.array([sim.rotation for sim in similarities], dtype=np.float64),
            np.array([sim.translation for sim in similarities], dtype=np.float64),
        )

    def __len__(self) -> int:
        return int(self.scale.shape[0])

    def __getitem__(self, k: int) -> Similarity:
        return Similarity._trusted(float(self.scale[k]), self.rotation[k].copy(), self.translation[k].copy())

    def take(self, keep: np.ndarray) -> PoseBatch:
        """The poses selected by an index array or a boolean mask."""
        return PoseBatch(self.scale[keep], self.rotation[keep], self.translation[keep])

    def assign(self, rows: np.ndarray, other: PoseBatch) -> PoseBatch:
        """A copy with poses ``rows`` (indices) replaced by ``other``'s, in order."""
        scale, rotation, translation = self.scale.copy(), self.rotation.copy(), self.translation.copy()
        scale[rows], rotation[rows], translation[rows] = other.scale, other.rotation, other.translation
        return PoseBatch(scale, rotation, translation)

    def where(self, use_other: np.ndarray, other: PoseBatch) -> PoseBatch:
        """Pose k from ``other`` where ``use_other[k]``, else from self."""
        return PoseBatch(
            np.where(use_other, other.scale, self.scale),
            np.where(use_other[:, None, None], other.rotation, self.rotation),
            np.where(use_other[:, None], other.translation, self.translation),
        )

    def apply(self, points: FloatArray) -> FloatArray:
        """Every pose applied to (n, m) points: (K, n, m)."""
        mapped: FloatArray = (points @ self.rotation.transpose(0, 2, 1)) * self.scale[:, None, None]
        return mapped + self.translation[:, None, :]

    def apply_inverse(self, points: FloatArray) -> FloatArray:
        """Every inverse ``R^T (y - t) / s`` applied to (n, m) points: (K, n, m)."""
        shifted = points[None, :, :] - self.translation[:, None, :]
        mapped: FloatArray = (shifted @ self.rotation) / self.scale[:, None, None]
        return mapped

    def motion(self, other: PoseBatch, mean: FloatArray, second_moment: FloatArray) -> FloatArray:
        """RMS of ||other_k(a) - self_k(a)|| over points a with this mean and second moment, per k.

        With D = s'R' - sR and d = t' - t: mean ||D a + d||^2 = tr(D M2 D^T) + 2 d.D mean + |d|^2,
        so the motion of every point is had from two moments, without touching the points.
        """
        lin = other.scale[:, None, None] * other.rotation - self.scale[:, None, None] * self.rotation
        shift = other.translation - self.translation
        value = np.einsum("kij,jl,kil->k", lin, second_moment, lin)
        value += 2.0 * np.einsum("ki,kij,j->k", shift, lin, mean) + np.einsum("ki,ki->k", shift, shift)
        motion: FloatArray = np.sqrt(np.maximum(value, 0.0))
        return motion
