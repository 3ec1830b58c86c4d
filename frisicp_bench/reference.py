"""Reference placement of two different shapes, which have no true relative pose.

Two silhouettes of one class (deer-2 against deer-1) are different drawings: no similarity maps
one onto the other exactly, so there is no ground truth. The benchmark uses a *reference*
instead: the similarity with the lowest symmetric RMS (:func:`.metrics.symmetric_rms`) found by
FRISICP started from a grid of placements around the whole circle. It is the best fit this
search finds, not a truth; results are compared with it, and their symmetric RMS relative to
its RMS says how close a method came to that best fit.
"""

from __future__ import annotations

import numpy as np

from frisicp_core import ConvergenceCriteria, FloatArray, Method, RegistrationConfig, Similarity, register

from .metrics import symmetric_rms

# Starts of the search: every 15 degrees, each at three scales around the ratio of RMS radii.
START_ANGLES = 24
START_SCALE_FACTORS = (0.8, 1.0, 1.25)
# Every start first gets a short single-level run; only the best few are refined to the end
# (refining all of them costs minutes and picks the same winner).
SCREENING_ITERATIONS = 15
REFINED_STARTS = 4


def start_placements(
    data: FloatArray,
    model: FloatArray,
    angles: int = START_ANGLES,
    scale_factors: tuple[float, ...] = START_SCALE_FACTORS,
) -> list[Similarity]:
    """2-D similarities putting the data's centroid on the model's, at each angle and scale."""
    if data.shape[1] != 2:
        raise ValueError("the reference search turns shapes in the plane: 2-D only")
    data_centroid, model_centroid = data.mean(axis=0), model.mean(axis=0)
    radius_ratio = float(
        np.sqrt(
            ((model - model_centroid) ** 2).sum(axis=1).mean()
            / ((data - data_centroid) ** 2).sum(axis=1).mean()
        )
    )
    starts = []
    for angle in np.linspace(0.0, 2.0 * np.pi, angles, endpoint=False):
        c, s = np.cos(angle), np.sin(angle)
        rotation = np.array([[c, -s], [s, c]])
        for factor in scale_factors:
            scale = radius_ratio * factor
            starts.append(Similarity(scale, rotation, model_centroid - scale * rotation @ data_centroid))
    return starts


def reference_placement(
    data: FloatArray, model: FloatArray, angles: int = START_ANGLES
) -> tuple[Similarity, float]:
    """The lowest-symmetric-RMS similarity over all starts, and that RMS.

    Every start is screened by a short single-level FRISICP run; the ``REFINED_STARTS`` best are
    refined by FRISICP with the paper's settings (no trimming: every point of both shapes
    counts, as in the score).
    """
    screening = ConvergenceCriteria(max_iterations=SCREENING_ITERATIONS)
    screened = []
    for start in start_placements(data, model, angles):
        config = RegistrationConfig.paper(Method.FRISICP, initial=start, levels=1, criteria=screening)
        similarity = register(data, model, config).similarity
        screened.append((symmetric_rms(similarity.apply(data), model), similarity))
    screened.sort(key=lambda scored: scored[0])
    refined = []
    for _, similarity in screened[:REFINED_STARTS]:
        result = register(data, model, RegistrationConfig.paper(Method.FRISICP, initial=similarity))
        refined.append((result.similarity, symmetric_rms(result.similarity.apply(data), model)))
    return min(refined, key=lambda placed: placed[1])
