"""A reliable cold answer's scale is probed a tolerance and a half either way
(frisicp_core.near_probes): a second minimum that fits as well past the tolerance means the scale
is not determined to it, and the answer is not reliable."""

from __future__ import annotations

import zlib

import numpy as np
import pytest
from support.data import SHARED_DATA, shared_file

from frisicp_bench import scenes
from frisicp_bench.metrics import pose_errors
from frisicp_bench.sensor import sensed_frames_case, visible
from frisicp_core import NearestNeighbors, RegistrationConfig, Similarity, Tolerance, downsample, register
from frisicp_core.near_probes import near_rival, worth_probing
from frisicp_core.refine import ModelNormals, Sets, polish
from frisicp_core.uncertainty import Uncertainty


def _sets(data: np.ndarray, model: np.ndarray) -> Sets:
    data_tree, model_tree = NearestNeighbors(data), NearestNeighbors(model)
    return Sets(data_tree, model_tree, data_tree.spacing(), model_tree.spacing(), ModelNormals(model_tree))


def _rival(data: np.ndarray, model: np.ndarray, pose: Similarity, tolerance: Tolerance):  # type: ignore[no-untyped-def]
    sets = _sets(data, model)
    centroid = data.mean(axis=0)
    answer = polish(pose, sets, centroid)
    diagonal = float(np.linalg.norm(model.max(axis=0) - model.min(axis=0)))
    rival = near_rival(
        answer.similarity,
        answer.pairs.rms()[0],
        sets,
        centroid,
        tolerance,
        diagonal,
        step_tolerance=0.0,
        noise_floor=True,
    )
    return answer.similarity, rival


def test_a_patch_of_a_flat_floor_fits_as_well_a_tolerance_and_a_half_larger() -> None:
    """A patch in the middle of a flat floor (sampled apart from it) lies on the floor at any
    scale about its centre: the probe's start stays where it was put, as good a fit as the
    answer, and is its rival."""
    rng = np.random.default_rng(11)
    floor = np.column_stack([rng.uniform(-1, 1, (20000, 2)), 0.001 * rng.normal(size=20000)])
    patch = np.column_stack([rng.uniform(-0.3, 0.3, (3000, 2)), 0.001 * rng.normal(size=3000)])
    tolerance = Tolerance()

    answer, rival = _rival(patch, floor, Similarity.identity(3), tolerance)

    assert rival is not None
    assert abs(np.log(rival.similarity.scale / answer.scale)) > tolerance.scale
    assert rival.separation > 1.0
    assert 0.95 < rival.rms_ratio < 1.05
    assert abs(rival.offset[0]) == abs(np.log(rival.similarity.scale / answer.scale))
    assert "second minimum" in rival.describe()


def test_a_curved_surface_pulls_both_probes_back_to_the_answer() -> None:
    """Half a noisy sphere against the whole: the curvature fixes the scale, both probes return
    within the tolerance, and there is no rival."""
    rng = np.random.default_rng(12)
    sphere = rng.normal(size=(20000, 3))
    sphere /= np.linalg.norm(sphere, axis=1, keepdims=True)
    model = sphere + 0.002 * rng.normal(size=sphere.shape)
    data = sphere[sphere[:, 2] > 0] + 0.002 * rng.normal(size=(int(np.sum(sphere[:, 2] > 0)), 3))

    _, rival = _rival(data, model, Similarity.identity(3), Tolerance())

    assert rival is None


def test_only_an_answer_whose_scale_spans_a_share_of_the_tolerance_is_probed() -> None:
    tolerance = Tolerance(scale=0.01)
    sigma = np.diag([0.001**2, 1e-6, 1e-6, 1e-6, 1e-6, 1e-6, 1e-6])
    assert worth_probing(Uncertainty(sigma, np.zeros(3)), tolerance)  # 3 sigma = 0.3 %
    sigma[0, 0] = 0.0005**2  # 3 sigma = 0.15 %
    assert not worth_probing(Uncertainty(sigma, np.zeros(3)), tolerance)


def test_a_second_minimum_counts_as_one_sigma_along_the_way_to_it() -> None:
    covariance = np.diag([1e-6, 1e-4, 1e-4, 1e-4, 1e-6, 1e-6, 1e-6])
    offset = np.array([0.012, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0])
    widened = Uncertainty(covariance, np.zeros(3)).including(offset)
    assert np.isclose(widened.scale, np.hypot(0.001, 0.012))
    assert np.isclose(widened.rotation_deg, np.degrees(0.01))


def test_a_noise_free_copy_is_not_probed_and_stays_reliable() -> None:
    rng = np.random.default_rng(13)
    model = rng.normal(size=(3000, 3)) * [1.0, 0.6, 0.3]
    truth = Similarity(1.7, np.eye(3), np.array([0.2, -0.1, 0.4]))
    result = register(truth.inverse().apply(model), model, RegistrationConfig())
    assert result.reliable, result.reason
    assert "second minimum" not in result.reason


@pytest.mark.real_data
def test_two_noisy_depth_frames_whose_scale_has_two_dips_are_not_reliable() -> None:
    """benchmarks/depth_sensor.py's case "frames dragon1 2 % 0.3 #1" at seven times the default
    noise, occluded, in the sensors' frames, both at the cap (``--noise 0.007 --draw 2``): the
    cold answer ended 1.42 % off in scale at a 3-sigma of 0.74 %, reliable. Nudged 1.5 % in
    scale, the polish rests at another minimum more than a tolerance away that fits as well; the
    answer is now refused, and its stated scale uncertainty covers its error."""
    shared_file("real/dragon1.xyz")
    rng = np.random.default_rng(zlib.crc32(b"frames/dragon1.xyz/0.02/0.3/1/draw 2"))
    scene = scenes.object_cloud(SHARED_DATA, "dragon1.xyz")
    case = sensed_frames_case(
        scene, "dragon1", 0.02, 0.3, 0.007, rng, visible, False, level=False
    ).in_sensor_frames()
    data, model = downsample(case.data, 10_000, rng), downsample(case.model, 10_000, rng)

    result = register(data, model)

    errors = pose_errors(result.similarity, case.truth, data, case.model_diagonal)
    assert errors.scale > 0.01  # the answer is wrong ...
    assert not result.reliable  # ... and says so
    assert "second minimum" in result.reason
    assert result.uncertainty is not None
    assert errors.scale < 3 * result.uncertainty.scale
