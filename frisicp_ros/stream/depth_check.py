"""Whether a data stream's clouds come in coarse depth steps, what to do, and when not to trust a pose.

A data cloud arrives in its sensor's frame, so its depth is the range from the frame's origin or
the distance along one of its axes: ``frisicp_core.depth_steps`` finds the shells a depth camera
quantises it into. Steps of a percent or more of the cloud's size let two clouds from nearby
viewpoints lock terrace onto terrace, a wrong pose the verdict cannot see (README, "Depth-sensor
noise"); averaging each cloud over voxels a step wide (``voxel_mode: centroid``) smooths them out
(:data:`AVERAGE_STEPS`), after which the advice is not given again.

Where the model cloud comes in coarse steps too (frames of one camera registered onto each other,
each in its sensor's frame), the verdict cannot be trusted: the halves that size the uncertainty
share the terraces, and a locked pose fits as well as a right one. :func:`terrace_refusal` says
why such a pose is not reliable, until the clouds are averaged as advised.
``benchmarks/depth_sensor.py`` measures what that refuses (its "through the stream" columns).

The sensor does not change from one cloud to the next, so :class:`DepthStepCheck` looks at the
first data cloud of each frame and then at every :data:`CHECK_EVERY`-th (once in 10 s at 10 Hz;
a look costs milliseconds, benchmarks/depth_steps.py).
"""

from __future__ import annotations

import numpy as np

from frisicp_core.depth_steps import DepthSteps, find_depth_steps
from frisicp_ros.stream.pointcloud2 import VoxelMode

CHECK_EVERY = 100
# The voxels advised, in depth steps. Frames at 2 % steps (benchmarks/depth_sensor.py --steps 0.02
# --suite frames): averaged on voxels one step wide (--average 1), 0 of 36 wrong and reliable
# and 30 right (docs/depth_sensor_averaged.md), where 7 and 15 were without; with the depths
# exactly on shells 0 and 28 (--on-shells, docs/depth_sensor_on_shells_averaged.md), where 1
# and 11 were. Two steps wide left 9 right (docs/depth_sensor_averaged_two_steps.md): too sparse.
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


def terrace_refusal(
    data: DepthSteps | None, model: DepthSteps | None, voxel_mode: str, voxel_size: float
) -> str:
    """Why a pose between clouds with these depth steps is not reliable, "" when nothing says so:
    both clouds come in coarse steps and are not averaged as :func:`depth_step_advice` advises."""
    advice = depth_step_advice(data, voxel_mode, voxel_size)
    if not advice or model is None or not model.coarse:
        return ""
    assert data is not None
    return (
        f"both clouds come in coarse depth steps (data: {data.step:.3g} at the median {data.depth}"
        f" {data.median_depth:.3g}; model: {model.step:.3g} at {model.median_depth:.3g}): nearby"
        f" views can register terrace onto terrace, which the verdict cannot tell from a fit; set"
        f" voxel_mode: centroid with voxel_size >= {AVERAGE_STEPS * data.step:.3g} to average them out"
    )
