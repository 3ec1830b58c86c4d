"""The default configuration registers partly overlapping clouds without being told the overlap.

A scan onto its map, the map onto a scan and two scans that share part of their surface, each
under the paper's protocol (a scale, a 10 degree turn and a 5 % shift of the data about its own
centroid). The overlap is estimated per direction and reported; the scale cannot win by shrinking
or swelling the data; the result carries a verdict.
"""

import numpy as np
import pytest
from support.bunny import bunny, scan_pose

from frisicp_core import (
    ConvergenceCriteria,
    Initialization,
    Method,
    RegistrationConfig,
    Similarity,
    axis_angle_rotation,
    bumpy_surface,
    register,
    rotation_angle,
)


def cap(points: np.ndarray, direction: list[float], share: float) -> np.ndarray:
    """The ``share`` of ``points`` farthest along ``direction``: what a scanner on that side sees."""
    along = points @ (np.asarray(direction) / np.linalg.norm(direction))
    return points[along >= np.quantile(along, 1.0 - share)]


# Independent samplings of one surface: a map, a scan of about a third of it, two half scans.
MAP = bumpy_surface(12000, seed=1)
SCAN = cap(bumpy_surface(12000, seed=2), [1.0, 0.3, 0.2], 0.35)
LEFT = cap(bumpy_surface(12000, seed=4), [1.0, -0.2, 0.1], 0.5)
RIGHT = cap(bumpy_surface(12000, seed=3), [0.6, 0.8, 0.0], 0.5)
CASES = {"scan onto map": (SCAN, MAP), "map onto scan": (MAP, SCAN), "scan onto scan": (LEFT, RIGHT)}


def perturbed(data: np.ndarray, model: np.ndarray, scale: float, seed: int) -> tuple[np.ndarray, Similarity]:
    """The paper's protocol: data scaled about its centroid, turned 10 degrees, shifted 5 % of the
    model's diagonal. Returns the moved data and the similarity that undoes it."""
    rng = np.random.default_rng(seed)
    centre = data.mean(axis=0)
    rotation = axis_angle_rotation(rng.normal(size=3), np.deg2rad(10.0))
    shift = rng.normal(size=3)
    shift *= 0.05 * np.linalg.norm(model.max(axis=0) - model.min(axis=0)) / np.linalg.norm(shift)
    move = Similarity.about(centre, scale, rotation, shift)
    return move.apply(data), move.inverse()


def pose_errors(estimate: Similarity, truth: Similarity) -> tuple[float, float]:
    """(rotation error in degrees, relative scale error)."""
    return np.rad2deg(rotation_angle(estimate.rotation @ truth.rotation.T)), abs(
        estimate.scale / truth.scale - 1
    )


@pytest.mark.parametrize("case", CASES)
@pytest.mark.parametrize("scale", [0.1, 1.0, 2.9])
def test_partial_overlap_is_registered_with_the_default_config(case, scale):
    data, model = CASES[case]
    moved, truth = perturbed(data, model, scale, seed=int(scale * 10))
    result = register(moved, model)
    rotation_error, scale_error = pose_errors(result.similarity, truth)
    assert rotation_error < 1.0 and scale_error < 0.01, (rotation_error, scale_error)
    assert result.reliable, result.reason


def test_the_overlap_is_estimated_separately_in_each_direction():
    """A scan in its map: every scan point is on the map, a third of the map is in the scan."""
    moved, _ = perturbed(SCAN, MAP, 1.7, seed=3)
    onto_map = register(moved, MAP)
    assert onto_map.overlap_forward > 0.85
    assert onto_map.overlap_backward == pytest.approx(0.35, abs=0.08)
    moved, _ = perturbed(MAP, SCAN, 0.6, seed=4)
    onto_scan = register(moved, SCAN)
    assert onto_scan.overlap_forward == pytest.approx(0.35, abs=0.08)
    assert onto_scan.overlap_backward > 0.85


def test_started_at_the_truth_a_partial_scan_stays_there():
    """The failure of the untrimmed objective: from the true pose it swelled the scan over the
    part of the map it never saw."""
    moved, truth = perturbed(SCAN, MAP, 0.4, seed=5)
    result = register(moved, MAP, RegistrationConfig(initial=truth))
    rotation_error, scale_error = pose_errors(result.similarity, truth)
    assert rotation_error < 0.5 and scale_error < 0.005
    assert result.warm_started


@pytest.mark.parametrize("wrong_scale", [0.5, 2.0])
def test_neither_shrinking_nor_swelling_the_data_wins(wrong_scale):
    """Started with the data at half or twice its true size, the registration comes back: no
    pose wins by shrinking the scan onto a piece of the map or swelling it over the rest."""
    moved, truth = perturbed(SCAN, MAP, 1.3, seed=6)
    start = Similarity(truth.scale * wrong_scale, truth.rotation, truth.translation)
    result = register(moved, MAP, RegistrationConfig(initial=start))
    rotation_error, scale_error = pose_errors(result.similarity, truth)
    assert rotation_error < 1.0 and scale_error < 0.01


def test_data_onto_model_and_model_onto_data_are_one_problem():
    """With the symmetric scale, registering A onto B gives the inverse of B onto A."""
    moved, _ = perturbed(SCAN, MAP, 2.2, seed=7)
    forward = register(moved, MAP).similarity
    backward = register(MAP, moved).similarity
    rotation_error, scale_error = pose_errors(forward @ backward, Similarity.identity(3))
    assert rotation_error < 0.5 and scale_error < 0.005


def test_paper_config_is_the_published_algorithm():
    config = RegistrationConfig.paper()
    assert config.overlap == 1.0 and config.max_distance is None
    assert config.initialization is Initialization.IDENTITY and config.levels == 3
    assert not (config.symmetric or config.dense_targets or config.acceleration)
    assert config.criteria == ConvergenceCriteria(noise_floor=False)
    assert RegistrationConfig.paper(Method.SCALE_ICP).levels == 1


def test_an_implausible_warm_start_is_retried_cold():
    """A poisoned start (a garbage estimate reused by a tracking node) never stays the answer."""
    moved, truth = perturbed(SCAN, MAP, 1.1, seed=8)
    poisoned = Similarity(1e-30, np.eye(3), np.zeros(3))
    result = register(moved, MAP, RegistrationConfig(initial=poisoned))
    rotation_error, scale_error = pose_errors(result.similarity, truth)
    assert rotation_error < 1.0 and scale_error < 0.01
    assert result.reliable and not result.warm_started


# --- real scans (../shared/data): the cases, a few scales each -------------------------


def placed(name: str) -> np.ndarray:
    """A Stanford scan in the common frame of bun.conf, or the reconstruction (already there)."""
    points = bunny(name)
    return points if name.startswith("bun_zipper") else scan_pose(name).apply(points)


@pytest.mark.real_data
@pytest.mark.parametrize(
    ("data_name", "model_name", "scale"),
    [
        ("bun090.ply", "bun_zipper.ply", 0.3),
        ("bun180.ply", "bun_zipper.ply", 2.9),
        ("bun270.ply", "bun_zipper.ply", 1.1),
        ("bun315.ply", "bun_zipper.ply", 0.1),
        ("bun_zipper.ply", "bun270.ply", 2.5),
        ("bun045.ply", "bun000.ply", 0.7),
        ("bun000.ply", "bun045.ply", 1.9),
    ],
)
def test_real_scans_in_both_directions(data_name, model_name, scale):
    data, model = placed(data_name), placed(model_name)
    moved, truth = perturbed(data, model, scale, seed=int(scale * 10))
    result = register(moved, model)
    rotation_error, scale_error = pose_errors(result.similarity, truth)
    diagonal = np.linalg.norm(model.max(axis=0) - model.min(axis=0))
    centre = moved.mean(axis=0)
    translation_error = np.linalg.norm(result.similarity.apply(centre) - truth.apply(centre)) / diagonal
    assert rotation_error < 1.0 and scale_error < 0.01 and translation_error < 0.005
    assert result.reliable, result.reason


@pytest.mark.real_data
def test_real_scan_with_outliers_and_noise():
    """bun270 onto the map with 20 % uniform outliers in its box, then with noise of 0.5 % of
    the diagonal per coordinate (the issue's robustness cases)."""
    scan, model = placed("bun270.ply"), placed("bun_zipper.ply")
    rng = np.random.default_rng(9)
    diagonal = np.linalg.norm(model.max(axis=0) - model.min(axis=0))
    outliers = rng.uniform(scan.min(axis=0), scan.max(axis=0), size=(len(scan) // 5, 3))
    for corrupted in (
        np.vstack([scan, outliers]),
        scan + rng.normal(scale=0.005 * diagonal, size=scan.shape),
    ):
        moved, truth = perturbed(corrupted, model, 1.5, seed=11)
        rotation_error, scale_error = pose_errors(register(moved, model).similarity, truth)
        assert rotation_error < 1.0 and scale_error < 0.01
