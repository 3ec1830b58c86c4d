"""Is a registration result believable? A plain verdict that code can act on without thresholds.

ICP always returns *some* similarity; a garbage cloud, a degenerate pairing or a run that stopped
early gives one too. :func:`judge` checks what any correct registration satisfies, whatever the
data:

- the numbers are finite and the run converged;
- each cloud is the points of one scene: its RMS radius is at most :data:`MAX_SPREAD` times its
  median radius. Real clouds give 1-3 (a lidar scan, dense near the sensor, about 3); numbers
  that are not coordinates (a wrong byte order, random bytes) span dozens of orders of magnitude
  and give 1e10 and more, and any "fit" to them is meaningless;
- the scale is within a factor :data:`SCALE_RANGE` of the ratio of the clouds' RMS radii (the
  moment estimate). Partial overlap moves the true scale away from that ratio by the ratio of the
  overlapping part's extent to the whole cloud's, a small factor; 1e-39 or 1e40 is never right;
- each direction's estimated overlap is above the smallest share the estimator may keep
  (:data:`frisicp_core.overlap.MIN_FRACTION`): an estimate pinned there wanted fewer pairs
  still, so no part of the clouds fits;
- the RMS of the pairs used is small against the model's size (:data:`MAX_RELATIVE_RMS` of its
  RMS radius): two clouds of the same surface fit far closer than that.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .ambiguity import Competitor
from .config import Tolerance
from .fit import Fit
from .overlap import MIN_FRACTION
from .points import MAX_SPREAD
from .similarity import Similarity
from .uncertainty import SIGMAS, Uncertainty

SCALE_RANGE = 10.0
MAX_RELATIVE_RMS = 0.1
# Largest share of near misses (frisicp_core.fit) a fitting pose leaves in the better direction:
# a gross-misfit check beside the probes and the uncertainty, which catch the subtler wrong
# answers. At 0.25 it refused 9 of 224 right answers of benchmarks/trustworthy.py (two real scans
# whose occlusion edges miss each other: 37-38 %) and caught no wrong one the others missed.
MAX_NEAR_SHARE = 0.5
# A clear fit: right crops of 10-60 % of the development scenes left up to 0.23 on the first
# dense level (real scan pairs more: their occlusion edges, above); the wrong poses of 5-10 % crops
# that passed MAX_NEAR_SHARE left 0.36-0.39, those of 30 % crops of furnished rooms 0.33-0.44.
# Only a clear fit may overrule the merit (frisicp_core.solver.compare_finalists), and only one
# may rival an answer that fits clearly (frisicp_core.registration's probes).
CLEAR_NEAR_SHARE = 0.25
# How a reason's clause for a component whose SIGMAS-sigma exceeds its tolerance begins (the only
# refusal that keeps the result's local uncertainty; benchmarks/widening.py reads these clauses).
UNDETERMINED = "not determined to the tolerance"


@dataclass(frozen=True)
class Verdict:
    """``reliable`` is True when every check passed; ``reason`` says which failed ('' if none).
    ``determined`` is False when a check other than the tolerance check failed: the clouds do
    not fit at the answer, or another distinct pose fits as well, so its local uncertainty says
    nothing about how far off it is (:meth:`frisicp_core.uncertainty.Uncertainty.undetermined`)."""

    reliable: bool
    reason: str = ""
    determined: bool = True


def judge(
    similarity: Similarity,
    *,
    converged: bool,
    rms: float,
    overlap_forward: float,
    overlap_backward: float,
    moment_scale: float,
    model_radius: float,
    spreads: tuple[float, float] = (1.0, 1.0),
    fit: Fit | None = None,
    competitor: Competitor | None = None,
    uncertainty: Uncertainty | None = None,
    tolerance: Tolerance | None = None,
    model_diagonal: float = 0.0,
) -> Verdict:
    """The verdict on one result.

    ``moment_scale`` = model RMS radius / data RMS radius; ``spreads`` = :func:`spread` of the
    data and the model. A NaN overlap (forward-only methods measure no backward one) is not judged.
    """
    problems = []
    overlaps = [v for v in (overlap_forward, overlap_backward) if not math.isnan(v)]
    if not all(math.isfinite(v) for v in (similarity.scale, rms, *overlaps)) or not overlaps:
        return Verdict(False, "the estimate is not finite", determined=False)
    if not converged:
        problems.append("did not converge")
    for side, value in zip(("data", "model"), spreads, strict=True):
        if not value <= MAX_SPREAD:
            problems.append(
                f"the {side} cloud is not the points of one scene: its RMS radius is {value:.3g} times"
                " its median radius (numbers spanning many orders of magnitude: wrong byte order,"
                " random bytes?)"
            )
    ratio = similarity.scale / moment_scale
    if not 1.0 / SCALE_RANGE <= ratio <= SCALE_RANGE:
        problems.append(
            f"scale {similarity.scale:.3g} is {ratio:.3g}x the clouds' size ratio {moment_scale:.3g}"
            f" (plausible: within {SCALE_RANGE:g}x)"
        )
    for side, value in (("data", overlap_forward), ("model", overlap_backward)):
        if value <= MIN_FRACTION * 1.01:
            problems.append(f"only {value:.1%} of the {side} points overlap the other cloud: no part fits")
    if rms > MAX_RELATIVE_RMS * model_radius:
        problems.append(
            f"RMS {rms:.3g} is {rms / model_radius:.1%} of the model's radius"
            f" (a fit is within {MAX_RELATIVE_RMS:.0%})"
        )
    if fit is not None and not fit.best_near_share <= MAX_NEAR_SHARE:
        problems.append(
            f"the clouds do not coincide where they meet: {fit.best_near_share:.0%} of the points near the"
            f" other cloud miss its surface (noise {fit.expected_residual:.3g}; a fit leaves at most"
            f" {MAX_NEAR_SHARE:.0%})"
        )
    if competitor is not None:
        # A competitor clearly below the answer's merit is a better pose the search did not settle
        # on (registration's probes); within the margin, an equal one.
        how = "better" if competitor.better else "as well"
        problems.append(
            f"ambiguous: another pose {competitor.separation:.1f} tolerances away fits {how} (merit"
            f" ratio {competitor.merit_ratio:.3f}; scale {competitor.similarity.scale:.6g},"
            f" turned {np.degrees(competitor.similarity.rotation_angle()):.3g} deg)"
        )
    determined = not problems
    if uncertainty is not None and tolerance is not None:
        problems.extend(uncertain_components(uncertainty, tolerance, model_diagonal))
    return Verdict(not problems, "; ".join(problems), determined)


def within_tolerance(uncertainty: Uncertainty, tolerance: Tolerance, diagonal: float) -> bool:
    """True when :data:`SIGMAS` sigmas of every component lie within its tolerance."""
    return not uncertain_components(uncertainty, tolerance, diagonal)


def uncertain_components(uncertainty: Uncertainty, tolerance: Tolerance, diagonal: float) -> list[str]:
    """What :func:`judge` says of each component whose :data:`SIGMAS` sigmas exceed its
    tolerance (none: an empty list)."""
    rotation, scale, translation = tolerance.limits(diagonal)
    checks = (
        ("rotation", uncertainty.rotation_deg, rotation, "deg"),
        ("scale", uncertainty.scale * 100.0, scale * 100.0, "%"),
        ("translation", uncertainty.translation, translation, ""),
    )
    return [
        f"{UNDETERMINED}: {SIGMAS:g} sigma of the {name} is {SIGMAS * sigma:.3g}{unit}"
        f" (tolerance {limit:.3g}{unit})"
        for name, sigma, limit, unit in checks
        if not SIGMAS * sigma <= limit
    ]
