"""Depth-sensor noise: errors along each point's ray, growing with the range, depth quantised.

The cases of :mod:`frisicp_bench.scenes` add isotropic Gaussian noise. A structured-light or
stereo camera errs differently (Khoshelham and Elberink 2012, "Accuracy and resolution of Kinect
depth data"): it measures disparity d = f b / z, so

- the error lies along the ray from the camera, with sigma growing as z^2;
- the depth is quantised: disparity comes in steps (whole or sub-pixels), so the depths a
  camera can report are shells about it, h(z) = z^2 dd / (f b) apart. A surface seen at an
  angle comes out as terraces.

Two frames from nearby viewpoints share nearly the same shells, and registration can lock the
terraces of one onto the other's instead of the surfaces: the artefact this module lets a
benchmark provoke (benchmarks/depth_sensor.py). Both magnitudes are given as shares of a length
(the scene's diagonal) at the median range of the cloud, so one number describes the same sensor
whatever the scene's units.

What a sensor at a place keeps of the points (a :data:`Sight`): :func:`visible`, the front
surface only (a z-buffer), optionally with the flying pixels of depth edges; :func:`ring_sampled`,
a spinning lidar's rings instead of a camera's raster, spread over each view; :func:`fixed_rings`,
rings at a real lidar's fixed elevations.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from frisicp_core import FloatArray

from .metrics import model_size
from .scenes import SceneCase, box_crop, protocol_similarity, resampled

# The camera stands this many times the view's size (its bounding-box diagonal) from the view's
# centroid, in a random direction.
CAMERA_DISTANCE = 1.5
# Occlusion (visible): points per pixel of the camera's grid on average, and how far behind a
# pixel's nearest point (a share of its range) a point still counts as the same surface.
POINTS_PER_PIXEL = 10
SURFACE_DEPTH = 0.02
# Rings (ring_sampled): each beam keeps the points within this share of the channels' spacing
# of its elevation.
BEAM = 0.1

# What a camera at a place keeps of the points in front of it: (points, camera) -> points.
Sight = Callable[[FloatArray, FloatArray], FloatArray]


def depth_sensor(
    points: FloatArray,
    camera: FloatArray,
    noise: float,
    step: float,
    rng: np.random.Generator,
    on_shells: bool = False,
    noise_rng: np.random.Generator | None = None,
) -> FloatArray:
    """``points`` as a depth camera at ``camera`` reports them: each range quantised in disparity,
    the depth step ``step`` at the median range (0: none), then Gaussian noise along the ray,
    sigma ``noise`` at the median range, both growing with the range squared. With
    ``on_shells`` the noise comes first and the quantisation last, as in a camera, whose
    reported depths lie exactly on its shells. With ``noise_rng`` the noise is drawn from that
    stream, and ``rng`` advanced as without it: the same case, another noise draw."""
    offsets = points - camera
    ranges = np.linalg.norm(offsets, axis=1)
    rays = offsets / ranges[:, None]
    median = float(np.median(ranges))
    draws = rng.normal(size=ranges.shape)
    if noise_rng is not None:
        draws = noise_rng.normal(size=ranges.shape)
    noisy = draws * noise * (ranges / median) ** 2
    reported = ranges + noisy if on_shells else ranges
    if step > 0:
        # Disparity 1 / z in steps of `quantum`: depth steps are z^2 * quantum apart, `step` at the
        # median range.
        quantum = step / median**2
        disparity = np.maximum(np.round(1.0 / np.maximum(reported, 1e-300) / quantum), 1.0) * quantum
        reported = 1.0 / disparity
    if not on_shells:
        reported = reported + noisy
    sensed: FloatArray = camera + rays * reported[:, None]
    return sensed


def visible(points: FloatArray, camera: FloatArray, flying: bool = False) -> FloatArray:
    """The points a camera at ``camera`` sees (a z-buffer): their directions, about the one to
    their centroid, on a grid of square pixels holding :data:`POINTS_PER_PIXEL` points on
    average over the grid's extent; in each pixel the points within :data:`SURFACE_DEPTH` of
    the nearest one's range (the front surface; what lies behind it is occluded).

    With ``flying``, each depth edge of the image (two neighbouring pixels whose front surfaces lie
    more than :data:`SURFACE_DEPTH` apart) also reports a *flying pixel*, as time-of-flight and
    structured-light cameras do: a point on the ray of the nearer pixel's front point, half-way
    between the two fronts' ranges."""
    offsets = points - camera
    ranges = np.linalg.norm(offsets, axis=1)
    axis = offsets.mean(axis=0)
    axis /= np.linalg.norm(axis)
    helper = np.eye(3)[int(np.argmin(np.abs(axis)))]
    across = np.cross(axis, helper)
    across /= np.linalg.norm(across)
    up = np.cross(axis, across)
    depth = offsets @ axis
    angles = np.column_stack([np.arctan2(offsets @ across, depth), np.arctan2(offsets @ up, depth)])
    low, extent = angles.min(axis=0), np.ptp(angles, axis=0)
    pixel = float(np.sqrt(max(extent[0] * extent[1], 1e-24) * POINTS_PER_PIXEL / points.shape[0]))
    cells = np.floor((angles - low) / pixel).astype(np.int64)
    rows, width = (int(cells[:, 0].max()) + 1, int(cells[:, 1].max()) + 1)
    key = cells[:, 0] * width + cells[:, 1]
    nearest = np.full(rows * width, np.inf)
    np.minimum.at(nearest, key, ranges)
    front = ranges <= nearest[key] * (1.0 + SURFACE_DEPTH)
    seen: FloatArray = points[front]
    if not flying:
        return seen
    # The image: each pixel's front range and the row of its first point at that range.
    image = nearest.reshape(rows, width)
    at_front = np.flatnonzero(ranges == nearest[key])
    pixels, first = np.unique(key[at_front], return_index=True)
    ray = np.full(nearest.size, -1)
    ray[pixels] = at_front[first]
    flown = []
    for near, far, near_ray in _edges(image, ray.reshape(image.shape)):
        flown.append(camera + offsets[near_ray] * (0.5 * (near + far) / ranges[near_ray])[:, None])
    return np.concatenate([seen, *flown])


def _edges(image: FloatArray, ray: np.ndarray) -> list[tuple[FloatArray, FloatArray, np.ndarray]]:
    """The depth edges between horizontally and vertically neighbouring pixels of ``image``
    (front ranges, inf where empty): per direction, the nearer front, the farther one and the
    nearer pixel's ray (a row of the points)."""
    found = []
    for first, second, first_ray, second_ray in (
        (image[:-1], image[1:], ray[:-1], ray[1:]),
        (image[:, :-1], image[:, 1:], ray[:, :-1], ray[:, 1:]),
    ):
        near, far = np.minimum(first, second), np.maximum(first, second)
        edge = np.isfinite(far) & (far > near * (1.0 + SURFACE_DEPTH))
        near_ray = np.where(first <= second, first_ray, second_ray)
        found.append((near[edge], far[edge], near_ray[edge]))
    return found


def ring_sampled(points: FloatArray, camera: FloatArray, channels: int) -> FloatArray:
    """The points a spinning lidar at ``camera`` with ``channels`` beams measures: its beams
    spread evenly over the points' elevations (about the frame's z axis), each keeping the
    points within :data:`BEAM` of the beams' spacing of its own elevation, so the cloud comes
    as rings, dense along them and sparse across."""
    elevation = _elevations(points, camera)
    low, high = float(elevation.min()), float(elevation.max())
    return _on_beams(points, elevation, low, (high - low) / max(channels - 1, 1))


def fixed_rings(points: FloatArray, camera: FloatArray, spacing: float) -> FloatArray:
    """The points a spinning lidar at ``camera`` measures whose beams stand at fixed elevations,
    the multiples of ``spacing`` (radians) about the frame's z axis, as a real lidar's do: every
    frame of it has its rings on the same cones about the sensor (:func:`ring_sampled` spreads
    its beams over each view instead). Each beam keeps the points within :data:`BEAM` of the
    spacing of its elevation."""
    return _on_beams(points, _elevations(points, camera), 0.0, spacing)


def _elevations(points: FloatArray, camera: FloatArray) -> FloatArray:
    """Each point's elevation seen from ``camera``, about the frame's z axis (radians)."""
    offsets = points - camera
    elevation: FloatArray = np.arcsin(np.clip(offsets[:, 2] / np.linalg.norm(offsets, axis=1), -1.0, 1.0))
    return elevation


def _on_beams(points: FloatArray, elevation: FloatArray, first: float, spacing: float) -> FloatArray:
    """The ``points`` whose ``elevation`` lies within :data:`BEAM` of ``spacing`` of a beam's, the
    beams at ``first`` + k ``spacing``."""
    spacing = max(spacing, 1e-12)
    beam = np.round((elevation - first) / spacing)
    kept: FloatArray = points[np.abs(elevation - (first + beam * spacing)) <= BEAM * spacing]
    return kept


def camera_facing(view: FloatArray, rng: np.random.Generator) -> FloatArray:
    """A camera :data:`CAMERA_DISTANCE` view sizes from the view's centroid, in a random direction."""
    direction = rng.normal(size=view.shape[1])
    camera: FloatArray = view.mean(axis=0) + CAMERA_DISTANCE * model_size(view) * direction / np.linalg.norm(
        direction
    )
    return camera


def sensed_frames_case(
    scene: FloatArray,
    name: str,
    step: float,
    shift: float,
    noise: float,
    rng: np.random.Generator,
    sight: Sight | None = None,
    on_shells: bool = False,
    level: bool = False,
    noise_rng: np.random.Generator | None = None,
    noisy: tuple[str, ...] = ("data", "model"),
) -> SceneCase:
    """Two overlapping depth frames: boxes of 40 % of the scene, ``shift`` of the box's width apart,
    each re-sampled from its own half of the scene's points and seen by its own camera (the second
    moved by the same offset as its box) with :func:`depth_sensor`'s errors (``noise`` and
    ``step`` as shares of the scene's diagonal); the data moved by a small motion (up to 5
    degrees, 1-5 % scale drift), as :func:`frisicp_bench.scenes.frames_case` does. With
    ``sight`` each camera keeps only what that says it measures (:func:`visible`,
    :func:`ring_sampled`); ``on_shells`` as :func:`depth_sensor` takes it. ``level``: the shift
    lies across the frame's z axis, the axis of a lidar's rings (a vehicle driving on: rings on
    the ground and on walls along the way can fall onto the other frame's). ``noise_rng`` draws
    the noise from a stream of its own (:func:`depth_sensor`) and ``noisy`` names the clouds that
    get it ("data", "model"): the same frames, other noise (``benchmarks/noise_bias.py``)."""
    diagonal = model_size(scene)
    first = scene[rng.integers(scene.shape[0])]
    halves = rng.random(scene.shape[0]) < 0.5
    view = box_crop(scene[halves], 0.4, rng, first)
    width = float(np.ptp(view, axis=0).max())
    direction = rng.normal(size=3)
    if level:
        direction[2] = 0.0
    offset = shift * width * direction / np.linalg.norm(direction)
    other = box_crop(scene[~halves], 0.4, rng, first + offset)
    camera = camera_facing(view, rng)

    def sensed(points: FloatArray, at: FloatArray, cloud: str) -> FloatArray:
        kept = resampled(points, rng.uniform(0.5, 1.0), 0.0, rng)
        return depth_sensor(
            kept if sight is None else sight(kept, at),
            at,
            noise * diagonal if cloud in noisy else 0.0,
            step * diagonal,
            rng,
            on_shells,
            noise_rng,
        )

    data = sensed(view, camera, "data")
    model = sensed(other, camera + offset, "model")
    scale = float(np.exp(rng.choice((-1.0, 1.0)) * rng.uniform(0.01, 0.05)))
    moved = protocol_similarity(model, scale, 5.0, rng)
    return SceneCase(
        f"{name} frames shift {shift:.2f}",
        "frames",
        moved.apply(data),
        model,
        moved.inverse(),
        (moved.apply(camera), camera + offset),
    )


def sensed_crop_case(
    scene: FloatArray,
    name: str,
    share: float,
    scale: float,
    step: float,
    noise: float,
    rng: np.random.Generator,
    sight: Sight | None = None,
    on_shells: bool = False,
) -> SceneCase:
    """A crop of ``share`` of the scene (30-100 % of its points kept) seen by a depth camera
    (:func:`depth_sensor`, ``on_shells`` as it takes it; with ``sight`` only what that keeps), moved by
    ``frisicp bench``'s protocol at ``scale`` (turned up to 30 degrees), onto the scene as it is
    (a map made otherwise)."""
    diagonal = model_size(scene)
    crop = resampled(box_crop(scene, share, rng), rng.uniform(0.3, 1.0), 0.0, rng)
    camera = camera_facing(crop, rng)
    if sight is not None:
        crop = sight(crop, camera)
    sensed = depth_sensor(crop, camera, noise * diagonal, step * diagonal, rng, on_shells)
    moved = protocol_similarity(scene, scale, 30.0, rng)
    return SceneCase(
        f"{name} {share:.0%} s={scale:.3g}",
        "crop onto scene",
        moved.apply(sensed),
        scene,
        moved.inverse(),
        (moved.apply(camera), None),
    )
