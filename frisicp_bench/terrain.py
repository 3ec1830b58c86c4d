"""A large synthetic terrain and a sensor driving over it: big maps and the scans that track in them.

The map is a height field z = h(x, y) over a square of :data:`SIDE` metres: the sum of four
octaves of Gaussian-smoothed white noise (features about 8, 3, 1 and 0.4 m wide, 2 m, 0.8 m,
0.3 m and 0.1 m high), sampled at any number of points (uniform in x and y, z by bilinear
interpolation of a 0.1 m grid). Random, so no two places look alike (a periodic pattern would
make tracking ambiguous); smooth at the map's spacing, rough at a scan's size, so a scan fixes
all six degrees of freedom, as a real outdoor scene does.

A *scan* is what a sensor at (x, y) sees within :data:`SCAN_RADIUS` metres (201 m^2, 2 % of the
map's area): a fresh uniform sample of the surface there (never the map's own points) with
Gaussian noise, expressed in the sensor's frame, model = truth(scan) with truth = the sensor's
pose composed with a fixed mounting similarity (scale :data:`MOUNTING_SCALE`: the scan is in
other units than the map, as FRISICP allows). The sensor drives a loop of radius
:data:`LOOP_RADIUS` about the map's centre at 0.5 m/s +- 30 %, its heading wobbling +- 10 degrees
about the loop's tangent (periods 7 s and 11 s), so the motion is not constant.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.ndimage import gaussian_filter

from frisicp_core import FloatArray, Similarity, axis_angle_rotation

SIDE = 100.0  # metres
GRID = 0.1  # metres between the height field's samples
# (feature width in metres, height in metres) of the octaves.
OCTAVES = ((8.0, 2.0), (3.0, 0.8), (1.0, 0.3), (0.4, 0.1))
SCAN_RADIUS = 8.0
NOISE = 0.01  # metres, Gaussian, on the scans (in the map frame)
LOOP_RADIUS = 25.0
SPEED = 0.5  # metres per second
MOUNTING_SCALE = 1.3
# The sensor's mounting: the scan's frame is turned and shifted against the vehicle's and in other
# units (model = pose @ mounting (scan)).
MOUNTING = Similarity(
    MOUNTING_SCALE, axis_angle_rotation([1.0, 0.2, 0.1], np.deg2rad(20.0)), np.array([0.4, -0.2, 1.8])
)


@dataclass
class Terrain:
    """The height field of one seed (module doc)."""

    seed: int = 0
    heights: FloatArray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        rng = np.random.default_rng(self.seed)
        cells = round(SIDE / GRID) + 1
        heights = np.zeros((cells, cells))
        for width, height in OCTAVES:
            octave = gaussian_filter(rng.normal(size=(cells, cells)), width / GRID / 2.0, mode="wrap")
            heights += height * octave / octave.std()
        self.heights = heights

    def height(self, x: FloatArray, y: FloatArray) -> FloatArray:
        """h(x, y) by bilinear interpolation (x, y within [0, SIDE])."""
        gx, gy = (
            np.clip(x / GRID, 0, self.heights.shape[0] - 1.001),
            np.clip(y / GRID, 0, self.heights.shape[1] - 1.001),
        )
        i, j = gx.astype(np.int64), gy.astype(np.int64)
        fx, fy = gx - i, gy - j
        h = self.heights
        value: FloatArray = (
            h[i, j] * (1 - fx) * (1 - fy)
            + h[i + 1, j] * fx * (1 - fy)
            + h[i, j + 1] * (1 - fx) * fy
            + h[i + 1, j + 1] * fx * fy
        )
        return value

    def map_points(self, count: int, seed: int = 1) -> FloatArray:
        """``count`` points of the surface, uniform over the square (the map)."""
        rng = np.random.default_rng(seed)
        x, y = rng.uniform(0.0, SIDE, count), rng.uniform(0.0, SIDE, count)
        return np.column_stack((x, y, self.height(x, y)))

    def scan(
        self, truth: Similarity, count: int, rng: np.random.Generator, reach: float = SCAN_RADIUS
    ) -> FloatArray:
        """``count`` noisy points within ``reach`` metres (in x and y) of where ``truth`` puts the
        sensor, in the sensor's frame (model = truth(scan))."""
        centre = truth.apply(np.zeros((1, 3)))[0]
        radius = reach * np.sqrt(rng.random(count))
        angle = rng.uniform(0.0, 2.0 * np.pi, count)
        x, y = centre[0] + radius * np.cos(angle), centre[1] + radius * np.sin(angle)
        surface = np.column_stack((x, y, self.height(x, y))) + rng.normal(scale=NOISE, size=(count, 3))
        return truth.inverse().apply(surface)

    def pose(self, seconds: float) -> Similarity:
        """The sensor's similarity (model = pose(scan)) ``seconds`` into the drive (module doc)."""
        travelled = SPEED * (seconds + 0.3 * 7.0 / (2 * np.pi) * (1 - np.cos(2 * np.pi * seconds / 7.0)))
        angle = travelled / LOOP_RADIUS
        x = SIDE / 2 + LOOP_RADIUS * np.cos(angle)
        y = SIDE / 2 + LOOP_RADIUS * np.sin(angle)
        heading = angle + np.pi / 2 + np.deg2rad(10.0) * np.sin(2 * np.pi * seconds / 11.0)
        z = float(self.height(np.array([x]), np.array([y]))[0])
        vehicle = Similarity(1.0, axis_angle_rotation([0.0, 0.0, 1.0], heading), np.array([x, y, z]))
        return vehicle @ MOUNTING


def scan_errors(estimate: Similarity, truth: Similarity, scan: FloatArray) -> tuple[float, float, float]:
    """Rotation error (degrees), relative scale error, and the error of where the scan lands (its
    centroid's image, model frame) as a share of the scan's bounding-box diagonal there."""
    rotation = float(
        np.degrees(Similarity(1.0, estimate.rotation @ truth.rotation.T, np.zeros(3)).rotation_angle())
    )
    scale = abs(estimate.scale / truth.scale - 1.0)
    centre = scan.mean(axis=0)
    shift = float(np.linalg.norm(estimate.apply(centre[None])[0] - truth.apply(centre[None])[0]))
    placed = truth.apply(scan)
    diagonal = float(np.linalg.norm(placed.max(axis=0) - placed.min(axis=0)))
    return rotation, scale, shift / diagonal
