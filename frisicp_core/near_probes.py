"""Is the answer pinned to the tolerance? A second minimum just past it.

The probes of :mod:`frisicp_core.ambiguity` look for rivals clearly apart from the answer
(10 degrees, a quarter octave, a fifth of the extent) and settle them on the thinned screening
level, where a minimum a tolerance or two from the answer is the answer's. The full sets can
hold such a second minimum all the same: the fit is flat over more than the tolerance along
some direction, with two dips at about the same height, and the covariance (the curvature at
the answer, widened by split halves that converge to the answer's dip) sees one of them. The
answer is then as likely the other, and reliable it is not.

So the polish (:func:`frisicp_core.refine.polish`, the full sets' point-to-plane steps) runs
again from the answer moved by :data:`NEAR_PROBE` tolerances either way, about the data
centroid's image (:func:`near_starts`): its scale times exp(+-1.5 scale tolerances), and turned
+-1.5 rotation tolerances about the axis its covariance determines worst. A start past the
tolerance that the data pull back comes back within it; one that ends more than a tolerance
from the answer (:func:`separation`) at an RMS within
:data:`~frisicp_core.ambiguity.AMBIGUITY_MARGIN` of the answer's, or below it, is a second
answer as good as the first: the pose is not determined to the tolerance. (The RMS of each
pose's kept pairs: the same sampled rows, most of them kept by both.) The scale is what noisy
or quantised depth makes flat, and the one component this package exists to add; a rotation
slides along a nearly round outline or about a dome's axis. Translations are not probed: a
sliding translation (a corridor, a plane) shows in the covariance, which sees the whole slide
along it as one flat direction.

A probe costs a polish (most of it the normals of the model points its start meets), so only a
reliable cold answer is probed, and a component only where
:data:`~frisicp_core.uncertainty.SIGMAS` of its sigmas span at least :data:`PROBED_FROM` of its
tolerance: a valley flat over more than the tolerance has a small curvature at its floor, and
the covariance of a dip that narrow (12 sigmas or more to the tolerance) puts the probes'
starts past 18 of its sigmas. A noiseless copy (0 sigma, ``make bench``) is never probed.

Measured (``benchmarks/depth_sensor.py --occlusion --sensor-frames --noise 0.007 --draw 2``;
test/core/test_near_probes.py): a pair of dragon frames at 2 % depth steps ended 1.42 % off in
scale at a 3-sigma of 0.74 %, reliable; polished from its scale times e^-0.015 it rests 1.2
tolerances away at an RMS 0.17 % lower.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .ambiguity import AMBIGUITY_MARGIN, separation
from .config import Tolerance
from .refine import Sets, difference, perturb, polish
from .rotations import vector_size
from .similarity import FloatArray, Similarity
from .uncertainty import SIGMAS, Uncertainty

# A component is probed only where 3 of its sigmas reach this share of its tolerance (module doc).
PROBED_FROM = 0.25
# How far the probes start from the answer, in tolerances of what they move, either way: past it,
# so a start the data pull back must come back across it, and near enough that the polish's
# steps reach it (they are linearised about the start).
NEAR_PROBE = 1.5


@dataclass(frozen=True)
class NearRival:
    """A second minimum near the answer: the pose, its separation from the answer in
    tolerances, its RMS over the answer's, and the perturbation taking the answer to it
    (:func:`~frisicp_core.refine.difference`: log scale ratio, rotation vector, displacement of
    the data centroid's image)."""

    similarity: Similarity
    separation: float
    rms_ratio: float
    offset: FloatArray

    def describe(self) -> str:
        return (
            f"a second minimum {self.separation:.1f} tolerances away fits as well (RMS ratio"
            f" {self.rms_ratio:.4f}; scale {self.similarity.scale:.6g}, turned"
            f" {np.degrees(self.similarity.rotation_angle()):.3g} deg): the pose is not determined to"
            " the tolerance"
        )


def near_starts(answer: Similarity, uncertainty: Uncertainty, tolerance: Tolerance) -> list[Similarity]:
    """The near probes' starts (module doc), about where ``answer`` puts the data's centroid
    (``uncertainty.centre``, the covariance's centre): its scale times exp(+-:data:`NEAR_PROBE`
    tolerances), where :data:`~frisicp_core.uncertainty.SIGMAS` sigmas of the scale span
    :data:`PROBED_FROM` of its tolerance; turned +-:data:`NEAR_PROBE` tolerances about the
    rotation's worst-determined axis (the rotation block's leading eigenvector), where the
    rotation's do."""
    m, r = answer.dim, vector_size(answer.dim)
    moves: list[FloatArray] = []
    if SIGMAS * uncertainty.scale >= PROBED_FROM * tolerance.scale:
        moves += [np.eye(1 + r + m)[0] * sign * NEAR_PROBE * tolerance.scale for sign in (-1.0, 1.0)]
    rotation = uncertainty.covariance[1 : 1 + r, 1 : 1 + r]
    if (
        np.all(np.isfinite(rotation))
        and SIGMAS * uncertainty.rotation_deg >= PROBED_FROM * tolerance.rotation_deg
    ):
        axis = np.linalg.eigh(rotation)[1][:, -1]
        angle = np.radians(NEAR_PROBE * tolerance.rotation_deg)
        for sign in (-1.0, 1.0):
            move = np.zeros(1 + r + m)
            move[1 : 1 + r] = sign * angle * axis
            moves.append(move)
    return [perturb(answer, move, uncertainty.centre) for move in moves]


def near_rival(
    answer: Similarity,
    answer_rms: float,
    starts: list[Similarity],
    sets: Sets,
    centroid: FloatArray,
    tolerance: Tolerance,
    diagonal: float,
    *,
    step_tolerance: float,
    noise_floor: bool,
) -> NearRival | None:
    """The first of the near probes' ``starts`` (:func:`near_starts`) whose polish ends apart
    from ``answer`` at an RMS within the margin of ``answer_rms`` (or below it), or None.
    ``sets`` are the polish's full sets, ``centroid`` the data's (data frame), ``diagonal`` the
    model's bounding-box diagonal; ``step_tolerance`` and ``noise_floor`` as the answer's own
    polish ran."""
    for start in starts:
        polished = polish(start, sets, centroid, tolerance=step_tolerance, noise_floor=noise_floor)
        rms = polished.pairs.rms()[0]
        apart = separation(polished.similarity, answer, centroid, diagonal, tolerance)
        ratio = rms / answer_rms if answer_rms > 0 else float("inf")
        if apart > 1.0 and ratio <= 1.0 + AMBIGUITY_MARGIN:
            offset = difference(polished.similarity, answer, centroid)
            return NearRival(polished.similarity, apart, ratio, offset)
    return None
