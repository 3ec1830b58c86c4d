"""How a registration is scored: pose errors against a known placement, and symmetric RMS.

Every method is scored by the same code on the full point sets, so the numbers compare across
methods whatever each one minimises internally.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from frisicp_core import FloatArray, Similarity, nearest, rotation_angle

# Success thresholds of the benchmark (issue 5): rotation, relative scale, translation relative
# to the model size.
MAX_ROTATION_DEG = 1.0
MAX_SCALE_ERROR = 0.01
MAX_TRANSLATION_ERROR = 0.005


@dataclass(frozen=True)
class PoseErrors:
    rotation_deg: float  # angle of R_est R_true^T
    scale: float  # |s_est / s_true - 1|
    translation: float  # see pose_errors

    @property
    def success(self) -> bool:
        return (
            self.rotation_deg < MAX_ROTATION_DEG
            and self.scale < MAX_SCALE_ERROR
            and self.translation < MAX_TRANSLATION_ERROR
        )


def model_size(model: FloatArray) -> float:
    """Diagonal of the model's axis-aligned bounding box: the length errors are relative to."""
    return float(np.linalg.norm(model.max(axis=0) - model.min(axis=0)))


def pose_errors(estimate: Similarity, truth: Similarity, data: FloatArray, size: float) -> PoseErrors:
    """Errors of ``estimate`` against ``truth`` (both map ``data`` into the model frame).

    The translation error is the distance between where the two transforms put the data's
    centroid, divided by ``size``: unlike ``|t_est - t_true|`` it does not depend on where the
    coordinate origin happens to be.
    """
    centroid = data.mean(axis=0)
    offset = np.linalg.norm(estimate.apply(centroid) - truth.apply(centroid))
    return PoseErrors(
        rotation_deg=float(np.degrees(rotation_angle(estimate.rotation @ truth.rotation.T))),
        scale=abs(estimate.scale / truth.scale - 1.0),
        translation=float(offset / size),
    )


def symmetric_rms(moved_data: FloatArray, model: FloatArray) -> float:
    """RMS of nearest-point distances both ways over all points (the FRISICP objective, Eq. 3).

    ``moved_data`` is the data already mapped into the model frame. Neither direction alone
    judges a scaled fit: data shrunk onto a piece of the model has a small forward error and a
    large backward one.
    """
    forward_sq, _ = nearest(model, moved_data)
    backward_sq, _ = nearest(moved_data, model)
    return float(np.sqrt((forward_sq.sum() + backward_sq.sum()) / (forward_sq.size + backward_sq.size)))
