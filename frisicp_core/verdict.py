"""Is a registration result believable? A plain verdict that code can act on without thresholds.

ICP always returns *some* similarity; a garbage cloud, a degenerate pairing or a run that stopped
early gives one too. :func:`judge` checks what any correct registration satisfies, whatever the
data:

- the numbers are finite and the run converged;
- the scale is within a factor :data:`SCALE_RANGE` of the ratio of the clouds' RMS radii (the
  moment estimate). Partial overlap moves the true scale away from that ratio by the ratio of the
  overlapping part's extent to the whole cloud's, a small factor; 1e-39 or 1e40 is never right;
- each direction's estimated overlap is at least :data:`MIN_OVERLAP`: below it, too few points
  carry the estimate to tell a fit from a coincidence;
- the RMS of the pairs used is small against the model's size (:data:`MAX_RELATIVE_RMS` of its
  RMS radius): two clouds of the same surface fit far closer than that.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from .similarity import Similarity

SCALE_RANGE = 10.0
MIN_OVERLAP = 0.05
MAX_RELATIVE_RMS = 0.1


@dataclass(frozen=True)
class Verdict:
    """``reliable`` is True when every check passed; ``reason`` says which failed ('' if none)."""

    reliable: bool
    reason: str = ""


def judge(
    similarity: Similarity,
    *,
    converged: bool,
    rms: float,
    overlap_forward: float,
    overlap_backward: float,
    moment_scale: float,
    model_radius: float,
) -> Verdict:
    """The verdict on one result; ``moment_scale`` = model RMS radius / data RMS radius."""
    problems = []
    # Forward-only methods measure no backward overlap (NaN): it is then not judged.
    overlaps = [v for v in (overlap_forward, overlap_backward) if not math.isnan(v)]
    if not all(math.isfinite(v) for v in (similarity.scale, rms, *overlaps)) or not overlaps:
        problems.append("the estimate is not finite")
    else:
        if not converged:
            problems.append("did not converge")
        ratio = similarity.scale / moment_scale
        if not 1.0 / SCALE_RANGE <= ratio <= SCALE_RANGE:
            problems.append(
                f"scale {similarity.scale:.3g} is {ratio:.3g}x the clouds' size ratio {moment_scale:.3g}"
                f" (plausible: within {SCALE_RANGE:g}x)"
            )
        smallest = min(overlaps)
        if smallest < MIN_OVERLAP:
            side = "data" if smallest == overlap_forward else "model"
            problems.append(f"only {smallest:.1%} of the {side} points overlap (need {MIN_OVERLAP:.0%})")
        if rms > MAX_RELATIVE_RMS * model_radius:
            problems.append(
                f"RMS {rms:.3g} is {rms / model_radius:.1%} of the model's radius"
                f" (a fit is within {MAX_RELATIVE_RMS:.0%})"
            )
    return Verdict(not problems, "; ".join(problems))
