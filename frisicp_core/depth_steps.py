"""Depth steps: does a cloud's depth come in quantised shells, and how far apart are they?

A structured-light or stereo camera measures disparity d = f b / z in steps (whole or
sub-pixels), so the depths it reports lie on shells whose inverse depths u = 1 / z are evenly
spaced, ``du`` apart: the depth step at depth z is ``z^2 du`` (Khoshelham and Elberink 2012).
A surface seen at an angle comes out as terraces, and two frames from nearby viewpoints, whose
shells nearly coincide, can be registered terrace onto terrace instead of surface onto surface:
a pose biased by degrees that the verdict cannot see (README, "Depth-sensor noise"). Averaging
the cloud over voxels a step wide (:func:`frisicp_core.voxel_centroids`) smooths the terraces.

:func:`find_depth_steps` looks for such shells in a cloud given in its sensor's frame (as a
camera driver publishes it), with the depth taken four ways: the range from the frame's origin
and the distance along each of its axes (x forward in a ROS body frame, z in an optical frame);
the cloud must lie in front (a positive depth for almost every point). For each it takes the
inverse depths' *coherence* at a trial spacing ``du``,

    R(du) = | mean_i exp(2 pi i u_i / du) |,

1 for points exactly on shells ``du`` apart, exp(-2 pi^2 sigma^2 / du^2) for shells blurred by
noise of sigma (in u), and about 1 / sqrt(n) for depths with no shells. All trial spacings at
once: the Fourier transform of a fine histogram of u. A comb of shells shows a narrow peak at
1 / du (width about one over the number of shells) and its harmonics; a surface facing the
sensor (one shell, with noise) and a few walls at chosen depths show broad ones instead, so a
peak counts only where the coherence a quarter of its frequency to either side is less than
half of it, across at least :data:`MIN_SHELLS` shells. The lowest such peak is the spacing
(higher ones are its harmonics), or half its frequency where the coherence there is nearly as
high (the shells of a comb only a few shells deep give a broad peak, and a narrow one at twice
their frequency).

Depths quantised along another direction (a cloud turned out of its sensor's frame, or moved
away from its origin) are not found: their shells are not planes or spheres of this frame.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from .similarity import FloatArray

# Depths tried: the range from the origin, then the distance along each axis.
DEPTHS = ("range", "x", "y", "z")
# Steps looked for, as shares of the cloud's bounding-box diagonal at its median depth: finer
# steps than the smallest are buried in any sensor's noise; coarser than the largest are not
# steps but the scene's own layout.
SMALLEST_STEP, LARGEST_STEP = 0.002, 0.1
# A comb of shells: its coherence at least MIN_COHERENCE and SIGNIFICANCE / sqrt(n), more than
# twice the coherence a quarter of its frequency to either side, across at least MIN_SHELLS
# shells of the central depths. Shells blurred by noise of sigma keep exp(-2 pi^2 sigma^2 / du^2),
# 0.2 at sigma = 0.29 du, and blurred shells still lock: at a floor of 0.3,
# benchmarks/depth_sensor.py's stereo-like noise (0.25 du) hid the shells of 33 of 36 frame pairs
# at 2 % steps, and one pair was registered terrace onto terrace, 1.1 % off in scale, reliable.
# Lower floors meet real surfaces: objects with no quantised depth seen from in front reach
# 0.10-0.19 (a decimated bunny the most; a one-off measurement, and test_depth_steps.py). Random
# depths' coherence at one frequency exceeds r with probability exp(-n r^2): at SIGNIFICANCE = 5,
# exp(-25), so none of a band's ten thousand frequencies does but in one cloud in millions.
MIN_COHERENCE = 0.2
SIGNIFICANCE = 5.0
MIN_SHELLS = 4.0
# A step at least this share of the cloud's diagonal is coarse: benchmarks/depth_sensor.py
# found frames 40 % of a scene wide locking terrace onto terrace at steps of 1.5 % of the
# scene's diagonal, none at 1.25 %; a step of 1 % of the scene is 1.3-1.7 % of such a frame's
# own (docs/depth_steps.md), so every locking step is flagged.
COARSE_SHARE = 0.01
# A comb's coherence at its own frequency is at least this share of that at twice it (blurred
# shells: exp(-2 pi^2 sigma^2 / du^2) against its fourth power; see _fundamental).
_HARMONIC = 0.8
# Points looked at (evenly strided: the answer does not depend on a seed) at most and at least
# (fewer: a comb hardly stands out of random depths' coherence), and histogram bins per smallest step and
# at most.
MAX_POINTS, MIN_POINTS = 20_000, 500
_BINS_PER_STEP = 8
_MAX_BINS = 1 << 20
# Share of the points that must lie in front along a depth, and the central share of the
# inverse depths used (stray points far off would stretch the histogram).
_IN_FRONT = 0.9
_CENTRAL = (2.0, 98.0)


@dataclass(frozen=True)
class DepthSteps:
    """Shells found in a cloud's depth (:func:`find_depth_steps`).

    ``depth``: how the depth is measured ("range" from the frame's origin, or "x", "y", "z"
    along that axis); ``step``: the shells' spacing at ``median_depth``, in the cloud's units;
    ``share``: ``step`` over the cloud's bounding-box diagonal; ``coherence``: R at the shells'
    spacing (1: exactly on shells); ``shells``: how many shells the central depths span.
    """

    depth: str
    step: float
    median_depth: float
    share: float
    coherence: float
    shells: float

    @property
    def coarse(self) -> bool:
        """A step of at least :data:`COARSE_SHARE` of the cloud's size (see the module doc)."""
        return self.share >= COARSE_SHARE

    def __str__(self) -> str:
        return (
            f"depth steps of {self.step:.3g} at the median {self.depth} {self.median_depth:.3g}"
            f" ({self.share:.2%} of the cloud's size, coherence {self.coherence:.2f})"
        )


def find_depth_steps(points: FloatArray, max_points: int = MAX_POINTS) -> DepthSteps | None:
    """The shells of ``points`` (an (N, 3) array of finite coordinates in the sensor's frame),
    or None where no depth of :data:`DEPTHS` shows them (module doc). Of several depths that
    do, the most coherent. Looks at ``max_points`` evenly strided points at most; 2-D clouds
    and clouds of fewer than :data:`MIN_POINTS` points give None."""
    if points.ndim != 2 or points.shape[1] != 3 or points.shape[0] < MIN_POINTS:
        return None
    # In units of a power of two about the largest coordinate (exact): no square overflows or
    # underflows, whatever the cloud's units; shells and shares do not depend on them.
    largest = float(np.max(np.abs(points)))
    if not (np.isfinite(largest) and largest > 0):
        return None
    unit = float(np.ldexp(1.0, np.frexp(largest)[1] - 1))  # largest / unit in [1, 2)
    diagonal = float(np.linalg.norm(points.max(axis=0) / unit - points.min(axis=0) / unit))
    if not diagonal > 0:
        return None
    sampled = points[:: max(1, points.shape[0] // max_points)] / unit
    found = [
        steps for depth in DEPTHS if (steps := _shells(depth, _depths(sampled, depth), diagonal)) is not None
    ]
    best = max(found, key=lambda steps: steps.coherence, default=None)
    return (
        None if best is None else replace(best, step=best.step * unit, median_depth=best.median_depth * unit)
    )


def _depths(points: FloatArray, depth: str) -> FloatArray:
    if depth == "range":
        ranges: FloatArray = np.sqrt(np.einsum("ij,ij->i", points, points))
        return ranges
    along: FloatArray = points[:, "xyz".index(depth)]
    return along


def _shells(depth: str, depths: FloatArray, diagonal: float) -> DepthSteps | None:
    """The shells of one depth measure (None: too few points in front, or no comb)."""
    # A point a billionth of the cloud's size from the sensor or nearer has no depth to speak of.
    ahead = depths[depths > 1e-9 * diagonal]
    if ahead.size < max(_IN_FRONT * depths.size, MIN_POINTS):
        return None
    inverse = 1.0 / ahead
    low, high = np.percentile(inverse, _CENTRAL)
    inverse = inverse[(inverse >= low) & (inverse <= high)]
    median = float(np.median(ahead))
    with np.errstate(divide="ignore", over="ignore"):
        finest, coarsest = (share * diagonal / median**2 for share in (SMALLEST_STEP, LARGEST_STEP))
    span = float(high - low)
    # A sensor all but at the cloud (depths a tiny share of its size) gives spacings past the floats.
    if not (0.0 < finest < coarsest < np.inf and span > MIN_SHELLS * finest):
        return None
    width = max(finest / _BINS_PER_STEP, span / _MAX_BINS)
    bins = int(span / width) + 1
    counts = np.bincount(((inverse - low) / width).astype(np.int64), minlength=bins)
    # Zero-padded four times: the transform samples the frequencies a quarter of a peak apart.
    padded = 4 * bins
    coherence = np.abs(np.fft.rfft(counts.astype(np.float64), n=padded)) / inverse.size
    frequency = np.arange(coherence.size) / (padded * width)
    floor = max(MIN_COHERENCE, SIGNIFICANCE / np.sqrt(inverse.size))
    for peak in _peaks(coherence, frequency, 1.0 / coarsest, 1.0 / finest, floor):
        if span * frequency[peak] < MIN_SHELLS:
            continue
        fundamental = _fundamental(coherence, frequency, peak, 1.0 / coarsest)
        spacing = 1.0 / frequency[fundamental]
        shells = span / spacing
        step = float(spacing * median**2)
        return DepthSteps(depth, step, median, step / diagonal, float(coherence[peak]), float(shells))
    return None


def _fundamental(coherence: FloatArray, frequency: FloatArray, peak: int, lowest: float) -> int:
    """The shells' own frequency for a narrow ``peak``: the peak itself, or the frequency half of
    it (again and again) where the coherence is nearly as high. A comb across a few shells only
    has a broad peak at its own frequency and a narrow one at twice it (the broad one fails the
    test of :func:`_peaks`), but any comb is as coherent at its own frequency as at twice it."""
    while frequency[peak] / 2 >= lowest:
        half = round(peak / 2)
        near = coherence[max(half - 2, 1) : half + 3]
        if near.max() < _HARMONIC * coherence[peak]:
            break
        peak = max(half - 2, 1) + int(np.argmax(near))
    return peak


def _peaks(
    coherence: FloatArray, frequency: FloatArray, lowest: float, highest: float, floor: float
) -> list[int]:
    """The narrow peaks of ``coherence`` between the frequencies ``lowest`` and ``highest``, lowest
    first: local maxima of at least ``floor`` and of half the band's largest, more
    than twice the largest coherence within a quarter of their frequency on either side (a peak's
    harmonics a quarter away fail this, as do the broad peaks of a few surfaces)."""
    band = np.flatnonzero((frequency >= lowest) & (frequency <= highest))
    band = band[(band > 0) & (band < coherence.size - 1)]
    if band.size == 0:
        return []
    threshold = max(floor, 0.5 * float(coherence[band].max()))
    tall = band[
        (coherence[band] >= threshold)
        & (coherence[band] >= coherence[band - 1])
        & (coherence[band] >= coherence[band + 1])
    ]
    narrow = []
    for peak in tall:
        sides = [
            coherence[int(np.floor(peak * a)) : int(np.ceil(peak * b)) + 1]
            for a, b in ((0.7, 0.8), (1.2, 1.3))
        ]
        if all(side.size and side.max() < 0.5 * coherence[peak] for side in sides):
            narrow.append(int(peak))
    return narrow
