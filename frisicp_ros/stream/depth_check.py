"""Whether a data stream's clouds come in coarse depth steps, what is done about it, what to set.

A data cloud arrives in its sensor's frame, so its depth is the range from the frame's origin or
the distance along one of its axes: ``frisicp_core.depth_steps`` finds the shells a depth camera
quantises it into. Steps of a percent or more of the cloud's size let two clouds from nearby
viewpoints lock terrace onto terrace, a wrong pose the verdict cannot see (README, "Depth-sensor
noise"); averaging each cloud over voxels a step wide smooths them out.

The core does that by itself where both clouds come in coarse steps (``average_depth_steps``, on
by default; :mod:`frisicp_core.terraces`), on the clouds it is given: the data already capped to
``max_points``. Averaged in the reader instead (``voxel_mode: centroid`` with ``voxel_size`` at
least a step: :func:`depth_step_advice` says so), before the cap, a voxel holds more points:
``benchmarks/depth_sensor.py``'s frame pairs at steps of 1 % came out 29 of 36 right and reliable
so (``--average 1``, docs/depth_sensor_averaged.md) against 24 averaged by the core after the cap
(``--sensor-frames``, docs/depth_sensor_sensor_frames.md), none wrong and reliable either way.
Clouds the settings average already are not averaged again by the core
(:func:`averaged_by_settings`): both averages, one over the other, left 24
(``--sensor-frames --average 1``, docs/depth_sensor_sensor_frames_averaged.md).

The sensor does not change from one cloud to the next, so :class:`DepthStepCheck` looks at the
first data cloud of each frame and then at every :data:`CHECK_EVERY`-th (once in 10 s at 10 Hz;
a look costs milliseconds, benchmarks/depth_steps.py).
"""

from __future__ import annotations

import numpy as np

from frisicp_core.depth_steps import DepthSteps, find_depth_steps
from frisicp_core.terraces import AVERAGE_STEPS
from frisicp_ros.stream.pointcloud2 import VoxelMode

__all__ = ["AVERAGE_STEPS", "CHECK_EVERY", "DepthStepCheck", "averaged_by_settings", "depth_step_advice"]

CHECK_EVERY = 100


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
            self.found = find_depth_steps(points)  # None for 2-D clouds
            self._frame = frame
            self._since_check = 0
        self._since_check += 1
        return self.found

    def reset(self) -> None:
        """Look at the next cloud anew (the settings that shape a read cloud changed)."""
        self.found = None
        self._frame = None
        self._since_check = 0


def averaged_by_settings(found: DepthSteps | None, voxel_mode: str, voxel_size: float) -> bool:
    """Whether the stream's voxel settings average the clouds over ``found``'s coarse steps
    already: ``voxel_mode`` centroid on voxels at least :data:`AVERAGE_STEPS` steps wide."""
    return (
        found is not None
        and found.coarse
        and voxel_mode == VoxelMode.CENTROID.value
        and voxel_size >= AVERAGE_STEPS * found.step
    )


def depth_step_advice(found: DepthSteps | None, voxel_mode: str = "first", voxel_size: float = 0.0) -> str:
    """What a user should hear about ``found`` ("" when nothing: no shells, fine ones, or the
    settings average the clouds already, :func:`averaged_by_settings`)."""
    if found is None or not found.coarse or averaged_by_settings(found, voxel_mode, voxel_size):
        return ""
    edge = f"{AVERAGE_STEPS * found.step:.3g}"
    return (
        f"data clouds come in {found}: clouds from nearby viewpoints can register terrace onto"
        f" terrace, a pose off by degrees that looks reliable (README, Depth-sensor noise), so"
        f" where the model comes in coarse steps too, both are registered as their averages over"
        f" voxels a step wide; set voxel_mode: centroid with voxel_size >= {edge} to average them"
        f" before the max_points cap instead (more points to each voxel)"
    )
