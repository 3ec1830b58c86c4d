"""Is the answer's scale pinned to the tolerance? A second minimum just past it.

The probes of :mod:`frisicp_core.ambiguity` look for rivals clearly apart from the answer
(10 degrees, a quarter octave, a fifth of the extent) and settle them on the thinned screening
level, where a minimum a tolerance or two from the answer is the answer's. A surface seen by a
noisy depth sensor can hold such a second minimum all the same: the fit along the scale is flat
over more than the tolerance, with two dips at the same height, and the covariance (the
curvature at the answer, widened by split halves that converge to the answer's dip) sees one of
them. The answer is then as likely the other, and reliable it is not.

So the polish (:func:`frisicp_core.refine.polish`, the full sets' point-to-plane steps) runs
again from the answer with its scale multiplied by exp(+-:data:`NEAR_PROBE` tolerances) about
the data centroid's image. A start past the tolerance that the data pull back comes back
within it; one that ends more than a tolerance from the answer (:func:`separation`) at an RMS
within :data:`~frisicp_core.ambiguity.AMBIGUITY_MARGIN` of the answer's, or below it, is a
second answer as good as the first: the scale is not determined to the tolerance. (The RMS of
each pose's kept pairs: the same sampled rows, most of them kept by both.) Only the scale is
probed: it is the component a quantised or noisy depth makes flat, and the one this package
exists to estimate. A probe costs a polish (most of it the normals of the model points its
start meets), so only a reliable cold answer is probed, and only where its scale's
:data:`~frisicp_core.uncertainty.SIGMAS` sigmas span at least :data:`PROBED_FROM` of the
tolerance (:func:`worth_probing`): a valley flat over more than the tolerance has a small
curvature at its floor, and the covariance of a dip that narrow (12 sigmas or more to the
tolerance) puts the probes' starts past 18 of its sigmas. (A noiseless copy, 0 sigma, is never
probed; on the real scenes about three in four reliable answers are.)

Measured (``benchmarks/depth_sensor.py --occlusion --sensor-frames --noise 0.007 --draw 2``,
README): a pair of dragon frames at 2 % depth steps ended 1.17 % off in scale at a 3-sigma of
0.82 %, reliable; nudged by 1.5 % in scale it ended 0.17 % off at an RMS 0.15 % higher.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .ambiguity import AMBIGUITY_MARGIN, separation
from .config import Tolerance
from .refine import Sets, difference, polish
from .similarity import FloatArray, Similarity
from .uncertainty import SIGMAS, Uncertainty

# Probed only where 3 sigmas of the scale reach this share of its tolerance (module doc).
PROBED_FROM = 0.25
# How far the probes start from the answer, in scale tolerances either way: past the tolerance,
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
            f" {self.rms_ratio:.4f}, scale {self.similarity.scale:.6g}): the scale is not determined"
            " to the tolerance"
        )


def worth_probing(uncertainty: Uncertainty, tolerance: Tolerance) -> bool:
    """Whether an answer of this ``uncertainty`` is near-probed (module doc)."""
    return SIGMAS * uncertainty.scale >= PROBED_FROM * tolerance.scale


def near_rival(
    answer: Similarity,
    answer_rms: float,
    sets: Sets,
    centroid: FloatArray,
    tolerance: Tolerance,
    diagonal: float,
    *,
    step_tolerance: float,
    noise_floor: bool,
) -> NearRival | None:
    """The first near probe (module doc) that ends apart from ``answer`` at an RMS within the
    margin of ``answer_rms`` (or below it), or None. ``sets`` are the polish's full sets,
    ``centroid`` the data's (data frame), ``diagonal`` the model's bounding-box diagonal;
    ``step_tolerance`` and ``noise_floor`` as the answer's own polish ran."""
    centre = answer.apply(centroid[None])[0]
    for sign in (-1.0, 1.0):
        factor = float(np.exp(sign * NEAR_PROBE * tolerance.scale))
        start = Similarity.about(centre, factor, np.eye(answer.dim)) @ answer
        polished = polish(start, sets, centroid, tolerance=step_tolerance, noise_floor=noise_floor)
        rms = polished.pairs.rms()[0]
        apart = separation(polished.similarity, answer, centroid, diagonal, tolerance)
        ratio = rms / answer_rms if answer_rms > 0 else float("inf")
        if apart > 1.0 and ratio <= 1.0 + AMBIGUITY_MARGIN:
            offset = difference(polished.similarity, answer, centroid)
            return NearRival(polished.similarity, apart, ratio, offset)
    return None
