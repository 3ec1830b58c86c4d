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
tolerances, :func:`separation`) with a merit within :data:`AMBIGUITY_MARGIN` of the answer's is a
competing answer: the data do not decide between the two. A probe that settles clearly lower
is a better answer the search missed.

The displaced starts only find rivals near the answer. A symmetric scene has an exact twin of
the answer far from it: a crop of a box-shaped room, a rack of shelves or a room with a
symmetric layout of furniture fits the scene as well turned half a turn about the scene's
centre, and a whole symmetric room fits its crop as well turned about its own centre. The
answer is also probed from those twins (:func:`half_turns`, :func:`symmetric_starts`): turned
half a turn about each principal axis of the data (data frame, about the data's centroid) and
of the model (about the model's centroid), the axes along which a symmetric cloud's half turns
lie. Without them 5 of 75 crops of synthetic symmetric rooms and shelves, both ways
(benchmarks/structured_scenes.py), came out 90-180 degrees off and reliable, no probe reaching
the twin.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .config import Tolerance
from .hypotheses import plane_rotations, principal_axes
from .similarity import FloatArray, Similarity, rotation_angle

PROBE_TURN_DEG = 10.0
PROBE_OCTAVE = 0.25
PROBE_SHIFT = 0.2
# A distinct pose whose merit is within this share of the answer's fits about as well.
AMBIGUITY_MARGIN = 0.05


@dataclass(frozen=True)
class Competitor:
    """A distinct pose that fits about as well as the answer: ``merit_ratio`` = its merit over
    the answer's (on the same points), ``separation`` its distance in tolerances."""

    similarity: Similarity
    merit_ratio: float
    separation: float


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


def half_turns(points: FloatArray) -> list[Similarity]:
    """Half turns about the centroid of ``points``: about each of its principal axes in 3-D, the
    plane's one half turn in 2-D. A cloud symmetric under a half turn has the turn's axis among
    its principal axes (its covariance is invariant under the turn)."""
    mean, _, axes = principal_axes(points)
    dim = points.shape[1]
    if dim == 2:
        return [Similarity.about(mean, 1.0, -np.eye(2))]
    return [Similarity.about(mean, 1.0, 2.0 * np.outer(axis, axis) - np.eye(dim)) for axis in axes.T]


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
    turn = np.degrees(rotation_angle(a.rotation @ b.rotation.T)) / tolerance.rotation_deg
    scale = abs(np.log(a.scale / b.scale)) / tolerance.scale
    shift = float(np.linalg.norm(a.apply(centre) - b.apply(centre))) / (tolerance.translation * diagonal)
    return float(max(turn, scale, shift))
