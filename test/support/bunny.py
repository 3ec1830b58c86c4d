"""Loading the Stanford bunny files of ../shared/data and their ground-truth poses."""

from __future__ import annotations

from functools import cache

import numpy as np

from frisicp_core import Similarity
from frisicp_core.io import read_points, read_scan_pose
from support.data import shared_file


def bunny(name: str) -> np.ndarray:
    """The vertices of a bunny file (read once per test session; callers get a copy)."""
    return _read_bunny(name).copy()


@cache
def _read_bunny(name: str) -> np.ndarray:
    return read_points(shared_file(f"bunny/{name}"))


def scan_pose(name: str) -> Similarity:
    """Pose of a scan in the common frame from bun.conf (metres)."""
    return read_scan_pose(shared_file("bunny/bun.conf"), name)
