"""Two clouds in a depth camera's coarse depth steps, averaged before they are registered.

A structured-light or stereo camera reports depths on shells (:mod:`frisicp_core.depth_steps`),
so a surface seen at an angle comes out as terraces. Two frames from nearby viewpoints, each in
its camera's frame, have nearly the same shells, and ICP fits terrace onto terrace better than
surface onto surface: a pose biased by degrees whose fit, spread and uncertainty look like a right
answer's (``benchmarks/depth_sensor.py``: 7-11 of 36 frame pairs at steps of 2 % of the scene wrong
and reliable, docs/depth_sensor.md). No check of the answer sees that bias: resampling the points
keeps the terraces.

Averaging each cloud over voxels :data:`AVERAGE_STEPS` step wide (:func:`voxel_centroids`) takes
the terraces out: the mean of a voxel's points lies near the surface, not on a shell. Registered
so, the same frame pairs came out 0 of 36 wrong and reliable, 30 right
(``--average 1``, docs/depth_sensor_averaged.md); two steps wide left too few points (9 of 36
right, none reliable, docs/depth_sensor_averaged_two_steps.md).

:func:`average_terraces` does that when both clouds show coarse steps about their own origins
(:attr:`DepthSteps.coarse`): clouds as a camera driver publishes them. Clouds moved out of their
sensors' frames show no shells and are registered as given, and so is a cloud with steps onto one
without (a camera frame onto a lidar map), which cannot lock terrace onto terrace. Clouds the
caller averaged already may still show their steps (a voxel's mean can lie near a shell) and are
averaged again, which thins them further for nothing (``--sensor-frames --average 1``,
docs/depth_sensor_sensor_frames_averaged.md): pass ``average_depth_steps=False`` for them, as the
node and ``frisicp bag`` do while their voxel settings average the data.

Where a voxel's walls fall is arbitrary, and the means move with them: a bias of the answer that
the split halves share. :func:`frisicp_core.registration.register` refines a reliable answer
again on grids moved by half a voxel (:meth:`Averaged.on_shifted_grids`) and widens its
covariance by the difference. What averaging leaves: ``benchmarks/depth_sensor.py
--sensor-frames`` and its variants (README, "Depth-sensor noise").
"""

from __future__ import annotations

from dataclasses import dataclass, replace

from .depth_steps import find_depth_steps
from .points import as_point_set
from .prepared import PreparedModel
from .similarity import FloatArray
from .voxel import voxel_centroids

# The voxels' edge, in depth steps at each cloud's median depth (module doc).
AVERAGE_STEPS = 1.0


@dataclass(frozen=True)
class Averaged:
    """Both clouds averaged over their depth steps: the points to register, the voxel edges used
    (data units, model units), and the clouds as given."""

    data: FloatArray
    model: PreparedModel
    edges: tuple[float, float]
    given: tuple[FloatArray, PreparedModel]

    def on_shifted_grids(self) -> Averaged:
        """The same averages on grids moved by half a voxel along every axis: where the voxels'
        walls fall is arbitrary, and what it moves in the answer is part of its uncertainty
        (:func:`frisicp_core.registration.register` measures it)."""
        data, model = self.given
        return replace(
            self,
            data=_averaged_data(data, self.edges[0], offset=0.5),
            model=model.averaged(self.edges[1], offset=0.5),
        )


def average_terraces(data: FloatArray, model: PreparedModel) -> Averaged | None:
    """``data`` (a validated point set) and ``model`` averaged over voxels :data:`AVERAGE_STEPS`
    of their own depth steps wide when both come in coarse steps, else None (module doc). The
    model's steps are looked for once (:attr:`PreparedModel.depth_steps`), the data's only where
    the model's are coarse; the model's average is prepared once per edge
    (:meth:`PreparedModel.averaged`), so a map registered against many times pays for neither
    again. Raises ``ValueError`` when an average is no usable point set (too few or degenerate
    points)."""
    if data.shape[1] != 3:
        return None
    model_steps = model.depth_steps
    if model_steps is None or not model_steps.coarse:
        return None
    data_steps = find_depth_steps(data)
    if data_steps is None or not data_steps.coarse:
        return None
    edges = (AVERAGE_STEPS * data_steps.step, AVERAGE_STEPS * model_steps.step)
    return Averaged(_averaged_data(data, edges[0]), model.averaged(edges[1]), edges, (data, model))


def _averaged_data(data: FloatArray, edge: float, offset: float = 0.0) -> FloatArray:
    """The data's voxel means (:func:`voxel_centroids`), validated as the model's average is
    (:meth:`PreparedModel.averaged`)."""
    return as_point_set(voxel_centroids(data, edge, offset), "data averaged over its depth steps")
