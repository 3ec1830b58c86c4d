"""Starting poses from the arrangement of large planes: rooms, corridors, buildings, furniture.

The descriptor search (:mod:`frisicp_core.global_search`) matches local shape. In a room of
boxes every patch of wall, floor or box face looks like every other, and its matches point
nowhere: furnished rooms registered onto 30 % crops of them found no start within 20 degrees of
the truth in either direction (docs/trust_history.md, 2026-12-07). What such scenes do have is a
few dominant plane directions (floor and ceiling, the walls) and the planes' offsets along them.
This stage reads the pose from those:

1. **Dominant directions** of each cloud (:mod:`frisicp_core.plane_directions`: the directions
   that hold a share of the normals of their own; the model's are its prepared model's).
2. **Rotations.** Every pair of the data's directions at least :data:`MIN_ANGLE` apart onto every
   ordered pair of the model's at the same angle (within :data:`ANGLE_AGREEMENT`), both signs
   each: the rotation taking one pair's frame (first direction, the pair's cross product, their
   completion) onto the other's. Duplicates within 2 degrees are dropped.
3. **Scale and shift along the frame's axes.** The points whose normals face an axis (within
   :data:`FACING`) lie on the planes across it, so their projections on the axis are a profile of
   plane offsets, one per cloud (bins of :data:`BIN` of the model's diagonal). For every scale of
   a ladder of 1/:data:`PER_OCTAVE` octave over :data:`OCTAVES` octaves either way of the RMS
   radius ratio, the shift that best lays the data's profile onto the model's: the cosine
   similarity of the two over their overlap (computed for all shifts at once by FFT), the overlap
   covering at least :data:`MIN_OVERLAP` of the longer profile (so that a cloud shrunk to a few
   bins cannot match a single peak) and :data:`MIN_SHARED` of the shorter (a crop lies within its
   scene). Per rotation, the :data:`SCALES_KEPT` best local maxima of the
   cosines summed over the three axes become poses; the :data:`SCALES_COMBINED` best of them
   with every combination of the :data:`SHIFTS_KEPT` best shifts per axis (a room's profile
   repeats itself: two walls, a row of cupboards). Only the facing points count: the rest of a
   cloud (the walls along the axis, the clutter) would make every profile a broad band that
   matches any other at a wrong scale.
4. **Ranking.** The poses are ranked by how much of the two clouds they make coincide
   (:func:`frisicp_core.global_search.coverage`) within :data:`COVERAGE_REACH` of the model's RMS
   radius: wider than the descriptor search's reach, because a rotation read from the directions
   is a degree or two off, which moves a room's far wall by more than the narrow reach. The best
   :data:`STARTS` are returned; ICP takes them from there with the other starts. (All poses are
   ranked first on about :data:`_FIRST_SAMPLE` points of each cloud, the best
   :data:`_SHORTLIST` again on the usual sample: a few thousand poses cost a few tenths of a
   second so.)

The stage runs only where the scene has plane structure (:func:`structured`): some cloud with two
directions of at least :data:`~frisicp_core.plane_directions.STRONG_SHARE` of its normals each. Smooth objects and cluttered table tops (the
bunny, the dragon, the chef figure, rs1) have none, and their registrations are as before.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from .global_search import coverage
from .plane_directions import PlaneDirections, plane_directions
from .points import rms_radius
from .similarity import FloatArray, Similarity, rotation_angle

if TYPE_CHECKING:
    from .prepared import PreparedModel

# Rotations: pairs of directions at least MIN_ANGLE apart whose angles agree within ANGLE_AGREEMENT.
MIN_ANGLE = np.deg2rad(30.0)
ANGLE_AGREEMENT = np.deg2rad(4.0)
_SAME_ROTATION = np.deg2rad(2.0)
# Profiles: points whose normals lie within FACING of an axis, in bins of BIN of the model's diagonal.
FACING = np.deg2rad(15.0)
BIN = 0.01
_MIN_FACING = 20
OCTAVES, PER_OCTAVE = 3, 16
MIN_OVERLAP, MIN_SHARED = 0.25, 0.5
SCALES_KEPT = 8
SHIFTS_KEPT, SCALES_COMBINED = 2, 3
# A runner-up shift lies this many bins from the best at least (another plane, not the same one).
_SHIFTS_APART = 5
COVERAGE_REACH = 0.1
# The first round of the ranking samples this many points of each cloud and keeps _SHORTLIST poses.
_FIRST_SAMPLE, _SHORTLIST = 100, 48
STARTS = 4


def structured(data: PlaneDirections, model: PlaneDirections) -> bool:
    """Whether the plane arrangement can say anything: both clouds have two directions, and one
    of them two strong ones (module doc)."""
    return min(len(data.directions), len(model.directions)) >= 2 and max(data.strong, model.strong) >= 2


def plane_starts(data: FloatArray, model: PreparedModel) -> list[Similarity]:
    """Starting poses for 3-D ``data`` onto ``model`` from their planes' arrangement (module
    doc), best first; none where the scene is not :func:`structured`."""
    theirs = model.plane_directions()  # kept by the prepared model
    if len(theirs.directions) < 2:
        return []  # not structured, whatever the data's directions
    ours = plane_directions(data)
    if not structured(ours, theirs):
        return []
    ratio = model.radius / rms_radius(data)
    scales = ratio * 2.0 ** (np.arange(-OCTAVES * PER_OCTAVE, OCTAVES * PER_OCTAVE + 1) / PER_OCTAVE)
    width = BIN * model.diagonal
    poses: list[Similarity] = []
    # The data's profiles depend on the pair of its directions only (the rotation turns its frame
    # onto the model's): made once per pair and axis, shared by the pair's rotations.
    profiles: dict[tuple[int, int, int], _ScaledProfiles | None] = {}
    for rotation, pair in _rotations(ours.directions, theirs.directions):
        poses += _rotation_poses(rotation, pair, ours, theirs, scales, width, profiles)
    if not poses:
        return []
    # Ranked in two rounds: all on a few points, the best of those on more.
    reach = COVERAGE_REACH * model.radius
    first = coverage(poses, data, model, reach, sample=_FIRST_SAMPLE)
    shortlist = [poses[k] for k in np.argsort(-first, kind="stable")[:_SHORTLIST]]
    shares = coverage(shortlist, data, model, reach)
    return [shortlist[k] for k in np.argsort(-shares, kind="stable")[:STARTS]]


def _rotation_poses(
    rotation: FloatArray,
    pair: tuple[int, int],
    ours: PlaneDirections,
    theirs: PlaneDirections,
    scales: FloatArray,
    width: float,
    profiles: dict[tuple[int, int, int], _ScaledProfiles | None],
) -> list[Similarity]:
    """The poses of one rotation (module doc, step 3), taking the data's profiles of its ``pair``
    of directions from ``profiles`` (filled where missing)."""
    facing = np.cos(FACING)
    frame = _frame(ours.directions[pair[0]], ours.directions[pair[1]])
    axes = rotation @ frame  # the data's frame turned onto the model's: columns
    model_along = theirs.points @ axes
    model_faces = np.abs(theirs.normals @ axes) > facing
    fits: list[_ProfileFit | None] = []
    total = np.zeros(scales.size)
    for axis in range(3):
        key = (*pair, axis)
        if key not in profiles:
            own = np.abs(ours.normals @ frame[:, axis]) > facing
            enough = np.count_nonzero(own) >= _MIN_FACING
            profiles[key] = (
                _ScaledProfiles.of(ours.points[own] @ frame[:, axis], scales, width) if enough else None
            )
        other = model_faces[:, axis]
        scaled = profiles[key]
        if scaled is None or np.count_nonzero(other) < _MIN_FACING:
            fits.append(None)
            continue
        fit = _profile_fit(scaled, model_along[other, axis], width)
        fits.append(fit)
        total += fit.best()
    padded = np.pad(total, 1, constant_values=-np.inf)
    peaks = np.flatnonzero((total >= padded[:-2]) & (total >= padded[2:]) & (total > 0))
    data_centre = ours.points.mean(axis=0) @ frame
    poses: list[Similarity] = []
    for rank, k in enumerate(peaks[np.argsort(-total[peaks], kind="stable")][:SCALES_KEPT]):
        # A room's profile repeats itself (two walls, a row of cupboards): at the best scales
        # the runner-up shift along any axis may be the right one.
        count = SHIFTS_KEPT if rank < SCALES_COMBINED else 1
        along = [
            fit.translations(int(k), count)
            if fit is not None
            # No planes across this axis: the centroids' offset.
            else np.full(1, model_along[:, axis].mean() - scales[k] * data_centre[axis])
            for axis, fit in enumerate(fits)
        ]
        poses += [
            Similarity(float(scales[k]), rotation, axes @ np.array(shift))
            for shift in itertools.product(*(np.unique(values) for values in along))
        ]
    return poses


def _frame(first: FloatArray, second: FloatArray) -> FloatArray:
    """The right-handed orthonormal frame (columns) of ``first`` and the normal of the two."""
    across = np.cross(first, second)
    across /= np.linalg.norm(across)
    return np.stack([first, np.cross(across, first), across], axis=1)


def _rotations(data: FloatArray, model: FloatArray) -> list[tuple[FloatArray, tuple[int, int]]]:
    """(rotation, the data's pair of directions) for every agreeing pair (module doc, step 2)."""
    found: list[tuple[FloatArray, tuple[int, int]]] = []
    for i, j in itertools.combinations(range(len(data)), 2):
        cosine = float(data[i] @ data[j])
        if abs(cosine) > np.cos(MIN_ANGLE):
            continue
        frame = _frame(data[i], data[j])
        angle = np.arccos(np.clip(cosine, -1.0, 1.0))
        for p, q in itertools.permutations(range(len(model)), 2):
            for first, second in _signed(model[p], model[q]):
                if abs(np.arccos(np.clip(first @ second, -1.0, 1.0)) - angle) > ANGLE_AGREEMENT:
                    continue
                rotation = _frame(first, second) @ frame.T
                if all(rotation_angle(rotation @ other.T) >= _SAME_ROTATION for other, _ in found):
                    found.append((rotation, (i, j)))
    return found


def _signed(first: FloatArray, second: FloatArray) -> tuple[tuple[FloatArray, FloatArray], ...]:
    """The four sign choices of two sign-free directions."""
    return ((first, second), (first, -second), (-first, second), (-first, -second))


@dataclass(frozen=True)
class _ProfileFit:
    """How the profile of ``s * data`` lies on that of the model along one axis, for each scale
    s of a ladder (rows) and each shift (columns, in bins: data bin i on model bin i + shift):
    the cosine over their overlap (0 where the overlap is too short)."""

    cosine: FloatArray  # (scales, shifts)
    shifts: np.ndarray  # (shifts,) in bins
    offsets: FloatArray  # (scales,): the translation of shift 0 at each scale
    width: float

    def best(self) -> FloatArray:
        """Each scale's best cosine."""
        best: FloatArray = self.cosine.max(axis=1)
        return best

    def translations(self, row: int, count: int) -> FloatArray:
        """The ``count`` translations t (model = s data + t) of scale ``row`` whose cosines are
        best, each :data:`_SHIFTS_APART` bins from those before it, best first (the best again
        where no other scores)."""
        cosine = self.cosine[row]
        chosen = [int(np.argmax(cosine))]
        while len(chosen) < count:
            far = np.all(np.abs(self.shifts[None] - self.shifts[chosen][:, None]) >= _SHIFTS_APART, axis=0)
            runner_up = int(np.argmax(np.where(far, cosine, 0.0)))
            chosen.append(runner_up if far[runner_up] and cosine[runner_up] > 0 else chosen[0])
        picked: FloatArray = self.offsets[row] + self.shifts[chosen] * self.width
        return picked


@dataclass(frozen=True)
class _ScaledProfiles:
    """One cloud's profile along one axis at every scale of a ladder (rows, each from bin 0 at
    the scaled cloud's lowest value ``starts``; ``lengths`` bins long), with each row's
    cumulative energy (sum of squares, a leading 0) and its spectra per FFT size."""

    profiles: FloatArray  # (scales, longest)
    starts: FloatArray
    lengths: np.ndarray
    energy: FloatArray  # (scales, longest + 1)
    spectra: dict[int, FloatArray]

    @classmethod
    def of(cls, values: FloatArray, scales: FloatArray, width: float) -> _ScaledProfiles:
        scaled = np.outer(scales, values)
        starts = scaled.min(axis=1)
        bins = ((scaled - starts[:, None]) / width).astype(np.int64)
        lengths = bins.max(axis=1) + 2
        longest = int(lengths.max())
        rows = np.repeat(np.arange(scales.size), values.size)
        counts = np.bincount(rows * longest + bins.ravel(), minlength=scales.size * longest)
        profiles = _smoothed(counts.reshape(scales.size, longest))
        energy = np.concatenate([np.zeros((scales.size, 1)), np.cumsum(profiles**2, axis=1)], axis=1)
        return cls(profiles, starts, lengths, energy, {})

    def spectrum(self, size: int) -> FloatArray:
        """The rows' conjugate spectra for FFTs of ``size`` (kept)."""
        if size not in self.spectra:
            self.spectra[size] = np.conj(np.fft.rfft(self.profiles, size, axis=1))
        return self.spectra[size]


def _profile_fit(data: _ScaledProfiles, model: FloatArray, width: float) -> _ProfileFit:
    """The data's profiles (one per scale s) against the profile of the ``model`` values, for
    every scale and shift (module doc, step 3): the products for all shifts at once by FFT,
    each divided by the two profiles' norms over their overlap (cumulative sums)."""
    origin = model.min()
    model_bins = int((model.max() - origin) / width) + 2
    model_profile = _smoothed(np.bincount(((model - origin) / width).astype(np.int64), minlength=model_bins))
    longest = data.profiles.shape[1]
    size = 1 << int(np.ceil(np.log2(model_bins + longest + 2)))
    products = np.fft.irfft(np.fft.rfft(model_profile, size)[None] * data.spectrum(size), size, axis=1)
    shifts = np.concatenate([np.arange(model_bins), np.arange(-(longest - 1), 0)])
    products = products[:, shifts % size]
    low = np.maximum(shifts[None], 0)
    high = np.minimum(model_bins, shifts[None] + data.lengths[:, None])
    model_energy = np.concatenate([[0.0], np.cumsum(model_profile**2)])
    over_model = model_energy[np.clip(high, 0, model_bins)] - model_energy[np.clip(low, 0, model_bins)]
    data_high = np.clip(high - shifts[None], 0, longest)
    data_low = np.clip(low - shifts[None], 0, longest)
    over_data = np.take_along_axis(data.energy, data_high, 1) - np.take_along_axis(data.energy, data_low, 1)
    overlap = high - low
    enough = (overlap >= MIN_OVERLAP * np.maximum(model_bins, data.lengths)[:, None]) & (
        overlap >= MIN_SHARED * np.minimum(model_bins, data.lengths)[:, None]
    )
    valid = enough & (over_model > 0) & (over_data > 0)
    with np.errstate(invalid="ignore", divide="ignore"):
        cosine = np.where(valid, products / np.sqrt(over_model * over_data), 0.0)
    return _ProfileFit(cosine, shifts, origin - data.starts, width)


def _smoothed(counts: np.ndarray) -> FloatArray:
    """Histograms (last axis) smoothed by [1/4, 1/2, 1/4], the ends padded with zeros."""
    padded = np.pad(counts.astype(np.float64), [(0, 0)] * (counts.ndim - 1) + [(1, 1)])
    smoothed: FloatArray = 0.25 * padded[..., :-2] + 0.5 * padded[..., 1:-1] + 0.25 * padded[..., 2:]
    return smoothed
