"""Loading the Stanford bunny files of ../shared/data and their ground-truth poses."""

from __future__ import annotations

from functools import cache
from pathlib import Path

import numpy as np

from frisicp_core import Similarity
from frisicp_core.io import read_points
from support.data import shared_file


def bunny(name: str) -> np.ndarray:
    """The vertices of a bunny file (read once per test session; callers get a copy)."""
    return _read_bunny(name).copy()


@cache
def _read_bunny(name: str) -> np.ndarray:
    return read_points(shared_file(f"bunny/{name}"))


def scan_pose(name: str) -> Similarity:
    """Pose of a scan in the common frame from bun.conf: p_common = R(q)^T p + t (see the data README)."""
    conf: Path = shared_file("bunny/bun.conf")
    for line in conf.read_text().splitlines():
        parts = line.split()
        if parts[:2] == ["bmesh", name]:
            values = np.array(parts[2:9], dtype=float)
            rotation = Similarity.from_quaternion(1.0, values[3:7], np.zeros(3)).rotation
            return Similarity(1.0, rotation.T, values[:3])
    raise KeyError(f"{name} is not in bun.conf")
