"""Cases with a known answer built from real scenes (../shared/data/real, its README's recipes).

Every case is a (data, model) pair and the similarity ``truth`` with model ~ truth(data), made
from real clouds by cropping, re-sampling, sensor-like noise, outliers and a chosen similarity:

- *crop onto scene*: a box holding a share f of the scene (5-60 %), re-sampled (a random
  subset) with Gaussian noise, moved by a similarity, registered onto the whole scene;
  *scene onto crop* the other way round;
- *sparse map onto scene*: the visual-SLAM case, a few thousand points of a crop with noise
  growing with the square of the range from a virtual camera, a share of outliers spread over
  its bounding box, at a scale of 0.01-100;
- *frames*: two overlapping views of one scene (boxes shifted by a fraction of their size),
  each re-sampled with its own noise, as consecutive depth frames;
- *pair*: two real scans of one object (``bunny_part1/2``, ``dragon1/2``) whose placement is a
  reference by careful rigid ICP, not a truth (said where used);
- *unrelated*: a cloud of another object (a sphere, a cube's surface, a cylinder, a plane, a
  random box, another real object): no answer exists, and a reliable result is wrong.

The similarity applied to the data follows ``frisicp bench``'s protocol (scale about the model
centroid, a rotation up to a bound about a random axis, a translation of a tenth of the model's
size) with the scale and the rotation bound chosen per suite.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from frisicp_core import FloatArray, Similarity, read_points

from .cases import random_rotation
from .datasets import require
from .metrics import model_size

# The real scenes and objects of ../shared/data/real (README there).
SCENES = ("cturtle.pcd", "rs1.pcd")
OBJECTS = ("chef.pcd",)
SCAN_PAIRS = (("bunny_part1.xyz", "bunny_part2.xyz"), ("dragon1.xyz", "dragon2.xyz"))
# Sensor-like noise: Gaussian, sigma this share of the scene's diagonal (1 cm on a 3.6 m room).
NOISE = 0.003


@dataclass(frozen=True)
class SceneCase:
    """One registration with a known answer (or, ``truth`` None, with none). ``sensors``: where
    the sensor that measured each cloud (data, model) stood, in that cloud's own coordinates
    (None: not measured by one sensor, or not said), as a stream sees a cloud in its sensor's
    frame about the origin."""

    name: str
    suite: str
    data: FloatArray
    model: FloatArray
    truth: Similarity | None
    sensors: tuple[FloatArray | None, FloatArray | None] = (None, None)

    @property
    def model_diagonal(self) -> float:
        return model_size(self.model)

    def in_sensor_frames(self) -> SceneCase:
        """The case with each measured cloud moved so that its sensor stands at the origin, as a
        camera driver publishes it (the truth moved with them; clouds without a sensor as they
        are): where :mod:`frisicp_core.terraces` can see a depth camera's shells."""
        data_sensor, model_sensor = (np.zeros(3) if at is None else at for at in self.sensors)
        truth = (
            None
            if self.truth is None
            else Similarity(1.0, np.eye(3), -model_sensor)
            @ self.truth
            @ Similarity(1.0, np.eye(3), data_sensor)
        )
        return replace(
            self,
            data=self.data - data_sensor,
            model=self.model - model_sensor,
            truth=truth,
            sensors=(
                None if self.sensors[0] is None else np.zeros(3),
                None if self.sensors[1] is None else np.zeros(3),
            ),
        )


def real_cloud(data_dir: Path, name: str) -> FloatArray:
    """The finite points of ``real/NAME`` (organised clouds keep NaN for missing depth)."""
    points = read_points(require(data_dir / "real" / name))[:, :3]
    return np.ascontiguousarray(points[np.isfinite(points).all(axis=1)])


def box_crop(
    scene: FloatArray, share: float, rng: np.random.Generator, centre: FloatArray | None = None
) -> FloatArray:
    """The points of ``scene`` in a cube about a random scene point (or ``centre``) holding
    ``share`` of them, found by bisection on the cube's half-width."""
    middle = scene[rng.integers(scene.shape[0])] if centre is None else centre
    distance = np.abs(scene - middle).max(axis=1)
    half = float(np.quantile(distance, share))
    return scene[distance <= half]


def resampled(points: FloatArray, keep: float, noise: float, rng: np.random.Generator) -> FloatArray:
    """A random ``keep`` share of ``points`` with isotropic Gaussian noise of sigma ``noise``."""
    count = max(4, round(keep * points.shape[0]))
    chosen = points[np.sort(rng.choice(points.shape[0], size=count, replace=False))]
    noisy: FloatArray = chosen + rng.normal(scale=noise, size=chosen.shape)
    return noisy


def protocol_similarity(
    model: FloatArray, scale: float, max_rotation_deg: float, rng: np.random.Generator
) -> Similarity:
    """``frisicp bench``'s perturbation: scale ``scale`` and a rotation up to the bound about the
    model centroid, then a shift of a tenth of the model's size in a random direction."""
    direction = rng.normal(size=model.shape[1])
    shift = 0.1 * model_size(model) * direction / np.linalg.norm(direction)
    rotation = random_rotation(model.shape[1], max_rotation_deg, rng)
    return Similarity.about(model.mean(axis=0), scale, rotation, shift)


def log_uniform_scale(low: float, high: float, rng: np.random.Generator) -> float:
    return float(np.exp(rng.uniform(np.log(low), np.log(high))))


def crop_case(
    scene: FloatArray,
    name: str,
    share: float,
    scale: float,
    rng: np.random.Generator,
    *,
    reverse: bool = False,
    max_rotation_deg: float = 30.0,
) -> SceneCase:
    """A re-sampled noisy crop onto its scene (``reverse``: the scene onto the crop)."""
    noise = NOISE * model_size(scene)
    crop = resampled(box_crop(scene, share, rng), rng.uniform(0.3, 1.0), noise, rng)
    data, model = (scene, crop) if reverse else (crop, scene)
    moved = protocol_similarity(model, scale, max_rotation_deg, rng)
    suite = "scene onto crop" if reverse else "crop onto scene"
    return SceneCase(f"{name} {share:.0%} s={scale:.3g}", suite, moved.apply(data), model, moved.inverse())


def sparse_map_case(
    scene: FloatArray,
    name: str,
    rng: np.random.Generator,
    *,
    points: int = 2000,
    outliers: float = 0.1,
    share: float = 0.5,
) -> SceneCase:
    """A sparse visual-SLAM-like map of part of the scene at a scale of 0.01-100: ``points``
    points of a crop, noise growing with the squared range from a camera placed a crop-size
    away, ``outliers`` of them replaced by points uniform in the crop's bounding box."""
    crop = box_crop(scene, share, rng)
    chosen = crop[rng.choice(crop.shape[0], size=min(points, crop.shape[0]), replace=False)]
    size = model_size(crop)
    direction = rng.normal(size=3)
    camera = chosen.mean(axis=0) + size * direction / np.linalg.norm(direction)
    ranges = np.linalg.norm(chosen - camera, axis=1)
    sigma = NOISE * model_size(scene) * (ranges / np.median(ranges)) ** 2
    noisy = chosen + rng.normal(size=chosen.shape) * sigma[:, None]
    wrong = rng.random(noisy.shape[0]) < outliers
    noisy[wrong] = rng.uniform(crop.min(axis=0), crop.max(axis=0), size=(int(wrong.sum()), 3))
    scale = log_uniform_scale(0.01, 100.0, rng)
    moved = protocol_similarity(scene, scale, 30.0, rng)
    return SceneCase(
        f"{name} sparse s={scale:.3g}", "sparse map onto scene", moved.apply(noisy), scene, moved.inverse()
    )


def frames_case(
    scene: FloatArray, name: str, share: float, step: float, rng: np.random.Generator
) -> SceneCase:
    """Two overlapping views, as consecutive frames: boxes of ``share`` of the scene whose
    centres are ``step`` of the box's width apart, each re-sampled from its own half of the
    scene's points (two frames never measure the same surface points) with its own noise, moved
    by a small motion (up to 5 degrees, 1-5 % scale drift)."""
    noise = NOISE * model_size(scene)
    first = scene[rng.integers(scene.shape[0])]
    halves = rng.random(scene.shape[0]) < 0.5
    view = box_crop(scene[halves], share, rng, first)
    width = float(np.ptp(view, axis=0).max())
    direction = rng.normal(size=3)
    second = first + step * width * direction / np.linalg.norm(direction)
    other = box_crop(scene[~halves], share, rng, second)
    data = resampled(view, rng.uniform(0.5, 1.0), noise, rng)
    model = resampled(other, rng.uniform(0.5, 1.0), noise, rng)
    scale = float(np.exp(rng.choice((-1.0, 1.0)) * rng.uniform(0.01, 0.05)))
    moved = protocol_similarity(model, scale, 5.0, rng)
    return SceneCase(f"{name} frames step {step:.2f}", "frames", moved.apply(data), model, moved.inverse())


def object_cloud(data_dir: Path, name: str) -> FloatArray:
    """A real object or scene by file name: ``bun*.ply`` from bunny/ (metres), else real/."""
    if name.startswith("bun") and name.endswith(".ply"):
        return read_points(require(data_dir / "bunny" / name))
    return real_cloud(data_dir, name)


def reference_placement(data: FloatArray, model: FloatArray) -> Similarity:
    """Where a real scan pair lies: a careful rigid registration (cold FRISICP search, then rigid
    ICP from it on the full sets with the noise floor off). A reference, not a truth."""
    from frisicp_core import ConvergenceCriteria, Method, RegistrationConfig, register

    start = register(data, model).similarity
    rigid = RegistrationConfig(
        method=Method.ICP,
        initial=Similarity(1.0, start.rotation, start.translation),
        criteria=ConvergenceCriteria(noise_floor=False),
    )
    return register(data, model, rigid).similarity


def pair_case(
    data: FloatArray,
    model: FloatArray,
    placement: Similarity,
    name: str,
    scale: float,
    rng: np.random.Generator,
) -> SceneCase:
    """A real scan pair placed by ``placement`` (data onto model), moved by the protocol's
    similarity at ``scale``."""
    moved = protocol_similarity(model, scale, 30.0, rng)
    return SceneCase(
        f"{name} s={scale:.3g}", "scan pair", moved.apply(data), model, placement @ moved.inverse()
    )


def turned_scan_case(
    scan: FloatArray, pose: Similarity, model: FloatArray, name: str, degrees: float, rng: np.random.Generator
) -> SceneCase:
    """A real scan (its pose into the model's frame given) turned by ``degrees`` about a random
    axis through its centroid and scaled by a log-uniform 0.5-2."""
    from frisicp_core import axis_angle_rotation

    placed = pose.apply(scan)
    axis = rng.normal(size=3)
    turn = Similarity.about(
        placed.mean(axis=0), log_uniform_scale(0.5, 2.0, rng), axis_angle_rotation(axis, np.deg2rad(degrees))
    )
    return SceneCase(f"{name} {degrees:.0f} deg", "scan turned", turn.apply(placed), model, turn.inverse())


def unrelated_shape(kind: str, count: int, rng: np.random.Generator) -> FloatArray:
    """A cloud of another object (unit size): a sphere, a cube's surface, a cylinder, a plane or a
    uniformly filled box."""
    if kind == "sphere":
        points = rng.normal(size=(count, 3))
        return points / np.linalg.norm(points, axis=1, keepdims=True)
    if kind == "cube":
        points = rng.uniform(-1.0, 1.0, size=(count, 3))
        face = rng.integers(3, size=count)
        points[np.arange(count), face] = np.sign(points[np.arange(count), face])
        return points
    if kind == "cylinder":
        angle = rng.uniform(0.0, 2.0 * np.pi, count)
        return np.column_stack([np.cos(angle), np.sin(angle), rng.uniform(-1.5, 1.5, count)])
    if kind == "plane":
        return np.column_stack([rng.uniform(-1.0, 1.0, size=(count, 2)), rng.normal(scale=1e-3, size=count)])
    if kind == "box":
        return rng.uniform(-1.0, 1.0, size=(count, 3)) * [1.0, 0.6, 0.4]
    raise ValueError(f"unknown shape {kind!r}")


UNRELATED = ("sphere", "cube", "cylinder", "plane", "box")


def unrelated_case(
    shape: FloatArray, obj: FloatArray, name: str, reverse: bool, rng: np.random.Generator
) -> SceneCase:
    """A cloud of another object registered onto ``obj`` (``reverse``: ``obj`` onto it): no
    answer exists, so any reliable result is wrong."""
    size = model_size(obj) / model_size(shape)
    other = shape * size + obj.mean(axis=0)
    data, model = (obj, other) if reverse else (other, obj)
    moved = protocol_similarity(model, log_uniform_scale(0.3, 3.0, rng), 30.0, rng)
    suite = "unrelated object"
    return SceneCase(f"{name}{' (back)' if reverse else ''}", suite, moved.apply(data), model, None)
