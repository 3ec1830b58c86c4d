"""Where the real data lives and how a test that needs it skips; random and axis rotations."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from frisicp_bench.datasets import default_data_dir
from frisicp_core import Similarity, axis_angle_rotation

# $FRISICP_DATA, else ../shared/data beside the repository: where frisicp bench and benchmarks/ look.
SHARED_DATA = default_data_dir()


def shared_file(relative: str) -> Path:
    """Path of a file in ../shared/data, or a skip saying why the test cannot run."""
    path = SHARED_DATA / relative
    if not path.exists():
        pytest.skip(f"real data {path} is absent (../shared is only beside the repo in CI and dev checkouts)")
    return path


def random_rotation(dim: int, rng: np.random.Generator) -> np.ndarray:
    """A uniformly random proper rotation (QR of a Gaussian matrix, signs fixed)."""
    q, r = np.linalg.qr(rng.normal(size=(dim, dim)))
    q = q * np.sign(np.diag(r))
    if np.linalg.det(q) < 0:
        q[:, 0] = -q[:, 0]
    return q


def axis_rotation(dim: int, degrees: float, axis: tuple[float, ...] = (0.3, 1.0, 0.2)) -> np.ndarray:
    """A rotation by ``degrees``: in 2-D about the origin, in 3-D about ``axis``."""
    angle = np.deg2rad(degrees)
    c, s = np.cos(angle), np.sin(angle)
    if dim == 2:
        return np.array([[c, -s], [s, c]])
    return axis_angle_rotation(axis, angle)


def with_absurd_scale(outcome: Any) -> Any:
    """A registered pair's outcome as the verdict leaves a scale of 1.5e40: unreliable, with a
    reason naming the scale (what a garbage cloud produced before the verdict existed)."""
    dim = outcome.result.similarity.dim
    return dataclasses.replace(
        outcome,
        result=dataclasses.replace(
            outcome.result,
            similarity=Similarity(1.5e40, np.eye(dim), np.zeros(dim)),
            reliable=False,
            reason="scale 1.5e+40 is far from the clouds' size ratio",
        ),
    )
