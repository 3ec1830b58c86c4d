"""The polish's steps (frisicp_core.refine.polish) come to rest at the objective's optimum, not
wherever they start: a step is judged on the rows the current pose keeps."""

import numpy as np

from frisicp_core import NearestNeighbors, Similarity, axis_angle_rotation
from frisicp_core.refine import ModelNormals, Sets, polish


def _surface(rng: np.random.Generator, count: int, low: float, high: float) -> np.ndarray:
    """Noisy samples of a wavy sheet over x in [low, high], y in [0, 2]."""
    x, y = rng.uniform(low, high, count), rng.uniform(0.0, 2.0, count)
    z = 0.15 * np.sin(3.0 * x) * np.cos(2.5 * y) + 0.1 * x * y
    return np.stack([x, y, z], axis=1) + rng.normal(scale=0.02, size=(count, 3))


def test_starts_a_few_sigmas_apart_come_to_rest_together() -> None:
    rng = np.random.default_rng(3)
    model = _surface(rng, 12000, 0.0, 2.0)
    data = _surface(rng, 8000, 0.4, 2.0)  # another sampling, another noise, part of the sheet
    data_tree, model_tree = NearestNeighbors(data), NearestNeighbors(model)
    sets = Sets(data_tree, model_tree, data_tree.spacing(), model_tree.spacing(), ModelNormals(model_tree))
    centroid = data.mean(axis=0)
    truth = Similarity(1.0, np.eye(3), np.zeros(3))
    ends = []
    for seed in range(6):
        turn = axis_angle_rotation(np.random.default_rng(seed).normal(size=3), np.deg2rad(0.5))
        start = Similarity.about(centroid, 1.004, turn, [0.003, -0.002, 0.002]) @ truth if seed else truth
        ends.append(polish(start, sets, centroid).similarity.apply(centroid[None])[0])
    spread = np.linalg.norm(np.array(ends) - ends[0], axis=1)
    # Each start is 0.5 deg, 0.4 % and ~4 mm off the truth. Judged on each pose's own trimmed
    # RMS the steps stopped near their starts (2.5-4.3 mm from the truth start's end); judged on
    # the same rows they come to rest about a millimetre from it (0.7-2.0 mm).
    assert np.median(spread[1:]) < 1.5e-3
