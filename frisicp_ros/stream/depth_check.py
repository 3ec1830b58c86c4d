"""Whether a data stream's clouds come in coarse depth steps, and what to do about it.

A data cloud arrives in its sensor's frame, so its depth is the range from the frame's origin or
the distance along one of its axes: ``frisicp_core.depth_steps`` finds the shells a depth camera
quantises it into. Steps of a percent or more of the cloud's size let two clouds from nearby
viewpoints lock terrace onto terrace, a wrong pose the verdict cannot see (README, "Depth-sensor
noise"); averaging each cloud over voxels a step wide (``voxel_mode: centroid``) smooths them out
(:data:`AVERAGE_STEPS`), after which the advice is not given again.

The sensor does not change from one cloud to the next, so :class:`DepthStepCheck` looks at the
first data cloud of each frame and then at every :data:`CHECK_EVERY`-th (about 10 ms on 20,000
points; once in 10 s at 10 Hz).
"""

from __future__ import annotations

import numpy as np

from frisicp_core.depth_steps import DepthSteps, find_depth_steps
from frisicp_ros.stream.pointcloud2 import VoxelMode

CHECK_EVERY = 100
# The voxels advised, in depth steps: benchmarks/depth_sensor.py --average 1 (both clouds averaged
# on voxels one step wide) had no wrong and reliable frames at 2 % steps, and 30 of 36 right
# where 24 were without; two steps wide (--average 2) left 9 of 36 right, the clouds too sparse.
AVERAGE_STEPS = 1


class DepthStepCheck:
    """The latest finding about the data stream's depth steps (None: none found, or not checked)."""

    def __init__(self) -> None:
        self.found: DepthSteps | None = None
        self._frame: str | None = None
        self._since_check = 0

    def look(self, points: np.ndarray, frame: str) -> DepthSteps | None:
        """The finding for a data cloud of ``points`` in ``frame``: looked at anew when the frame
        changed or :data:`CHECK_EVERY` clouds after the last look, else the last one's."""
        if frame != self._frame or self._since_check >= CHECK_EVERY:
            self.found = find_depth_steps(points) if points.ndim == 2 and points.shape[1] == 3 else None
            self._frame = frame
            self._since_check = 0
        self._since_check += 1
        return self.found

    def reset(self) -> None:
        """Look at the next cloud anew (the settings that shape a read cloud changed)."""
        self.found = None
        self._frame = None
        self._since_check = 0


def depth_step_advice(found: DepthSteps | None, voxel_mode: str = "first", voxel_size: float = 0.0) -> str:
    """What a user should hear about ``found`` ("" when nothing: no shells, fine ones, or the
    clouds are averaged as advised already: ``voxel_mode`` centroid on voxels at least
    :data:`AVERAGE_STEPS` steps wide, whose centroids can still lie on shells where a voxel
    meets one shell only)."""
    if found is None or not found.coarse:
        return ""
    if voxel_mode == VoxelMode.CENTROID.value and voxel_size >= AVERAGE_STEPS * found.step:
        return ""
    return (
        f"data clouds come in {found}: clouds from nearby viewpoints can register terrace onto"
        f" terrace, a pose off by degrees that looks reliable (README, Depth-sensor noise); set"
        f" voxel_mode: centroid with voxel_size >= {AVERAGE_STEPS * found.step:.3g} to average them out"
    )
