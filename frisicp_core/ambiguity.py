"""Is the answer the only pose that fits? Probes around it, and how far apart two answers are.

A registration returns the best minimum its search found. When the clouds do not determine the
pose (a crop of a wall, a dome-shaped depth frame, a scene onto a crop that is mostly floor),
other poses fit about as well, and which one wins is an accident of sampling and noise; when
the search missed the right basin, the right pose may fit better than the answer. Neither shows
in the answer's own residuals. So the answer is *probed*: started again from poses displaced by
a clearly wrong amount (turned by :data:`PROBE_TURN_DEG` about each axis, scaled by
2^(+-:data:`PROBE_OCTAVE`), shifted by :data:`PROBE_SHIFT` of the data's extent, each about the
data's centroid), ICP runs from each. Probes that come back to the answer say its basin is
wide and unique around it; a probe that settles at a *distinct* pose (farther than the
tolerances, :func:`separation`) with a merit within the margin of the answer's is a competing
answer: the data do not decide between the two. A probe that settles clearly lower is a better
answer the search missed.

The margin is :data:`AMBIGUITY_MARGIN`; for a twin of the answer (below), :data:`MERIT_SIGMAS`
standard errors of the two merits' ratio where that is wider (:func:`merit_margin`). A merit is
TrICP's psi = e / xi^3 of each direction (:mod:`frisicp_core.overlap`), and the kept share xi of
a pose far from the answer counts other points than the answer's: which points a half-turned
crop meets is a fresh draw of the clouds' sampling. Twins in two independent samplings of a
symmetric room came out up to 16 % apart in merit; outside a fixed 5 %, the worse twin was never
called a rival, and came out reliable (benchmarks/structured_scenes.py). A near probe's rival
keeps most of the answer's points, and there 5 % tells them apart.

The displaced starts only find rivals near the answer. A symmetric scene has an exact twin of
the answer far from it: a crop of a box-shaped room, a rack of shelves or a room with a
symmetric layout of furniture fits the scene as well turned half a turn about the scene's
centre, and a whole symmetric room fits its crop as well turned about its own centre. The
answer is also probed from those twins (:func:`half_turns`, :func:`symmetric_starts`): turned
half a turn about each principal axis of the data (data frame, about the data's centroid) and
of the model (about the model's centroid), the axes along which a symmetric cloud's half turns
lie. Without them 8 of 144 crops of synthetic symmetric scenes (benchmarks/structured_scenes.py)
came out reliable turned 60-180 degrees, 1.6 times too large or a shelf bay along; with them none
(and none of 144 fresh ones).
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from .config import Tolerance
from .hypotheses import plane_rotations, principal_axes
from .overlap import TRIM_LAMBDA, Selection
from .similarity import FloatArray, Similarity, rotation_angle

PROBE_TURN_DEG = 10.0
PROBE_OCTAVE = 0.25
PROBE_SHIFT = 0.2
# A distinct pose whose merit is within this share of the answer's fits about as well, or within
# this many standard errors of the merits' ratio where that is wider (merit_margin).
AMBIGUITY_MARGIN = 0.05
MERIT_SIGMAS = 3.0


@dataclass(frozen=True)
class Competitor:
    """A distinct pose that fits about as well as the answer: ``merit_ratio`` = its merit over
    the answer's (on the same points), ``separation`` its distance in tolerances."""

    similarity: Similarity
    merit_ratio: float
    separation: float
    margin: float = AMBIGUITY_MARGIN

    @property
    def better(self) -> bool:
        """Whether the competitor's merit is below the answer's by more than the margin."""
        return self.merit_ratio < 1.0 - self.margin


def probe_starts(sim: Similarity, centre: FloatArray, extent: float) -> list[Similarity]:
    """The displaced starts of the module doc: ``centre`` is the data centroid's image and
    ``extent`` the data's RMS radius, both in the model frame."""
    dim = sim.dim
    turns = [Similarity.about(centre, 1.0, q) for q in plane_rotations(dim, np.deg2rad(PROBE_TURN_DEG))]
    scales = [Similarity.about(centre, 2.0**k, np.eye(dim)) for k in (PROBE_OCTAVE, -PROBE_OCTAVE)]
    shifts = [
        Similarity(1.0, np.eye(dim), PROBE_SHIFT * extent * sign * axis)
        for axis in np.eye(dim)
        for sign in (1.0, -1.0)
    ]
    return [move @ sim for move in turns + scales + shifts]


def merit_noise(selections: Sequence[Selection | None], row: int = 0) -> float:
    """The relative standard error of the merit sqrt(psi_f + psi_b) of pose ``row`` from its
    kept pairs.

    Each direction's psi = e / xi^(1 + lambda) (:mod:`frisicp_core.overlap`): e, a mean of the
    m kept squared distances, has a relative variance of about 1 / m (squared distances spread
    about as much as their mean); xi = m / n, a count of the points that meet the other cloud,
    (1 - xi) / m (a binomial share). Independent to first order: var(log psi) = (1 +
    (1 + lambda)^2 (1 - xi)) / m. The sum's relative variance weighs each by its psi^2, the
    square root halves it. The count's share assumes points placed at random (a random
    sampling, the node's random cap); a regular sampling (a contour, a full depth image) varies
    less, and this overstates it (twice, at 20 % overlap: test/core/test_symmetric_scenes.py)."""
    terms, total = 0.0, 0.0
    for selection in selections:
        if selection is None:
            continue
        kept, psi = float(selection.kept[row]), float(selection.merit[row])
        if kept <= 0 or not np.isfinite(psi):
            return float("inf")
        share = kept / selection.keep.shape[1]
        terms += psi**2 * (1.0 + (1.0 + TRIM_LAMBDA) ** 2 * (1.0 - share)) / kept
        total += psi
    return float(0.5 * np.sqrt(terms) / total) if total > 0 else float("inf")


def merit_ratio(rival: float, answer: float) -> float:
    """A rival's merit over the answer's (a ``Competitor.merit_ratio``). Two exact fits (both 0:
    a copy of a grid cloud and its half turn) fit as well as each other, 1; a rival beside an
    exact answer fits infinitely worse."""
    if answer > 0.0:
        return rival / answer
    return 1.0 if rival == 0.0 else float("inf")


def merit_margin(answer_noise: float, rival_noise: float) -> float:
    """How far a rival's merit ratio may lie from 1 and still fit as well (module doc): the
    larger of :data:`AMBIGUITY_MARGIN` and :data:`MERIT_SIGMAS` standard errors of the ratio of
    two independent merits with these relative standard errors (:func:`merit_noise`)."""
    return max(AMBIGUITY_MARGIN, MERIT_SIGMAS * float(np.hypot(answer_noise, rival_noise)))


def half_turns(points: FloatArray) -> list[Similarity]:
    """Half turns about the centroid of ``points`` in each plane of two of its principal axes: a
    cloud symmetric under a half turn has the turn's plane spanned by principal axes (its
    covariance is invariant under the turn). In 3-D these are the turns about each axis,
    2 a a^T - I; in 2-D the one turn, -I."""
    mean, _, axes = principal_axes(points)
    dim = points.shape[1]
    if dim == 2:
        turns = [-np.eye(2)]
    elif dim == 3:
        turns = [2.0 * np.outer(axis, axis) - np.eye(3) for axis in axes.T]
    else:
        turns = [
            np.eye(dim) - 2.0 * (np.outer(axes[:, i], axes[:, i]) + np.outer(axes[:, j], axes[:, j]))
            for i, j in itertools.combinations(range(dim), 2)
        ]
    return [Similarity.about(mean, 1.0, turn) for turn in turns]


def symmetric_starts(
    sim: Similarity, data_turns: list[Similarity], model_turns: list[Similarity]
) -> list[Similarity]:
    """The answer ``sim`` from its twins (module doc): each half turn of the data
    (:func:`half_turns`, data frame) before it, each of the model's after it."""
    return [sim @ turn for turn in data_turns] + [turn @ sim for turn in model_turns]


def separation(
    a: Similarity, b: Similarity, centre: FloatArray, diagonal: float, tolerance: Tolerance
) -> float:
    """How far apart two poses are, in tolerances: the largest of the rotation between them over
    ``tolerance.rotation_deg``, their log scale ratio over ``tolerance.scale`` and the distance
    between where they put the data point ``centre`` over ``tolerance.translation * diagonal``."""
    turn_limit, scale_limit, shift_limit = tolerance.limits(diagonal)
    turn = np.degrees(rotation_angle(a.rotation @ b.rotation.T)) / turn_limit
    scale = abs(np.log(a.scale / b.scale)) / scale_limit
    shift = float(np.linalg.norm(a.apply(centre) - b.apply(centre))) / shift_limit
    return float(max(turn, scale, shift))
