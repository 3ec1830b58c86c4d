"""A reliable cold answer is probed a tolerance and a half either way in scale and about its
worst-determined axis (frisicp_core.near_probes): a second minimum that fits as well past the
tolerance means the pose is not determined to it, and the answer is not reliable."""

from __future__ import annotations

import zlib

import numpy as np
import pytest
from support.data import SHARED_DATA, shared_file

from frisicp_bench import scenes
from frisicp_bench.metrics import pose_errors
from frisicp_bench.sensor import sensed_frames_case, visible
from frisicp_core import NearestNeighbors, RegistrationConfig, Similarity, Tolerance, downsample, register
from frisicp_core.near_probes import NEAR_PROBE, NearRival, near_rival, near_starts
from frisicp_core.refine import ModelNormals, Sets, polish
from frisicp_core.uncertainty import Uncertainty


def _sets(data: np.ndarray, model: np.ndarray) -> Sets:
    data_tree, model_tree = NearestNeighbors(data), NearestNeighbors(model)
    return Sets(data_tree, model_tree, data_tree.spacing(), model_tree.spacing(), ModelNormals(model_tree))


def _rival(
    data: np.ndarray, model: np.ndarray, pose: Similarity, tolerance: Tolerance
) -> tuple[Similarity, NearRival | None]:
    """The polished answer from ``pose``, and its near rival from starts in scale and about the
    z axis (the uncertainty of a flat, level patch: scale and that turn unknown)."""
    sets = _sets(data, model)
    centroid = data.mean(axis=0)
    answer = polish(pose, sets, centroid)
    diagonal = float(np.linalg.norm(model.max(axis=0) - model.min(axis=0)))
    loose = Uncertainty(
        np.diag([0.01, 1e-8, 1e-8, 0.01, 1e-8, 1e-8, 1e-8]), answer.similarity.apply(centroid)
    )
    rival = near_rival(
        answer.similarity,
        answer.pairs.rms()[0],
        near_starts(answer.similarity, loose, tolerance),
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


def test_a_curved_surface_pulls_every_probe_back_to_the_answer() -> None:
    """Half a noisy ellipsoid (axes 1, 0.7, 0.4) against the whole: its curvature fixes the
    scale and every turn, each probe returns within the tolerance, and there is no rival. (Half
    a sphere would not do: it fits the whole turned about any axis.)"""
    rng = np.random.default_rng(12)
    ellipsoid = rng.normal(size=(20000, 3))
    ellipsoid *= np.array([1.0, 0.7, 0.4]) / np.linalg.norm(ellipsoid, axis=1, keepdims=True)
    model = ellipsoid + 0.002 * rng.normal(size=ellipsoid.shape)
    upper = ellipsoid[ellipsoid[:, 0] > 0]
    data = upper + 0.002 * rng.normal(size=upper.shape)

    _, rival = _rival(data, model, Similarity.identity(3), Tolerance())

    assert rival is None


def test_a_component_is_probed_where_three_sigmas_span_a_quarter_of_its_tolerance() -> None:
    tolerance = Tolerance(scale=0.01, rotation_deg=1.0)
    answer = Similarity(2.0, np.eye(3), np.array([1.0, 0.0, 0.0]))
    centre = np.array([1.0, 2.0, 3.0])
    # 3 sigma: 0.3 % in scale, 0.15 degrees about y, far less about x and z.
    covariance = np.diag([0.001**2, 1e-12, np.radians(0.05) ** 2, 1e-12, 1e-6, 1e-6, 1e-6])

    starts = near_starts(answer, Uncertainty(covariance, centre), tolerance)

    assert [round(start.scale / answer.scale, 6) for start in starts] == [
        round(np.exp(-NEAR_PROBE * 0.01), 6),
        round(np.exp(NEAR_PROBE * 0.01), 6),
    ]
    # Every start leaves where the answer puts the centre's preimage in place.
    for start in starts:
        assert np.allclose(start.apply(answer.inverse().apply(centre[None])), centre)
    covariance[2, 2] = np.radians(0.1) ** 2  # 3 sigma 0.3 degrees about y: probed there too
    turned = near_starts(answer, Uncertainty(covariance, centre), tolerance)[2:]
    assert len(turned) == 2
    for start in turned:
        relative = start.rotation @ answer.rotation.T
        assert np.isclose(np.degrees(start.rotation_angle()), NEAR_PROBE * 1.0)
        assert np.allclose(np.abs(relative[:, 1]), [0.0, 1.0, 0.0])  # about y


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
