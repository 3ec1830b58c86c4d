"""Every result states its uncertainty: a covariance in a documented layout, converted to ROS's
pose covariance, growing with noise and along directions the clouds do not determine."""

from __future__ import annotations

import numpy as np
import pytest

from frisicp_core import (
    RegistrationConfig,
    Similarity,
    axis_angle_rotation,
    bumpy_surface,
    register,
    rotation_angle,
)
from frisicp_core.rotations import exp_rotation
from frisicp_core.uncertainty import Uncertainty

TRUTH = Similarity(0.25, axis_angle_rotation([0.1, 0.4, 1.0], 0.8), np.array([1.0, 2.0, 0.5]))


def perturbed(sim: Similarity, xi: np.ndarray, centre: np.ndarray) -> Similarity:
    """exp(xi) applied about ``centre`` on the left of ``sim`` (the layout of the covariance)."""
    turn = exp_rotation(xi[1:4], 3)
    scale = np.exp(xi[0])
    return Similarity(
        sim.scale * scale, turn @ sim.rotation, centre + scale * turn @ (sim.translation - centre) + xi[4:]
    )


def test_the_covariance_carried_to_another_point_matches_sampling() -> None:
    rng = np.random.default_rng(1)
    root = rng.normal(size=(7, 7)) * np.array([0.01, 0.02, 0.01, 0.03, 0.1, 0.2, 0.05])
    uncertainty = Uncertainty(root @ root.T, np.array([1.0, 0.0, 2.0]))
    point = np.array([4.0, -3.0, 1.0])
    samples = rng.multivariate_normal(np.zeros(7), uncertainty.covariance, size=20000) * 1e-3
    moved = np.array(
        [perturbed(TRUTH, xi, uncertainty.centre).apply(TRUTH.inverse().apply(point)) for xi in samples]
    )
    expected = uncertainty.at(point).covariance[4:, 4:] * 1e-6
    assert np.cov(moved.T) == pytest.approx(expected, rel=0.05, abs=0.05 * np.abs(expected).max())


def test_the_ros_pose_covariance_is_position_then_roll_pitch_yaw_at_the_origin() -> None:
    covariance = np.diag([1e-4, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0])
    uncertainty = Uncertainty(covariance, np.zeros(3))
    pose = uncertainty.pose_covariance(Similarity(1.0, np.eye(3), np.zeros(3)))
    assert np.diag(pose) == pytest.approx([4.0, 5.0, 6.0, 1.0, 2.0, 3.0])
    planar = Uncertainty(np.diag([1e-4, 7.0, 1.0, 2.0]), np.zeros(2))
    pose_2d = planar.pose_covariance(Similarity(1.0, np.eye(2), np.zeros(2)))
    assert np.diag(pose_2d) == pytest.approx([1.0, 2.0, 0.0, 0.0, 0.0, 7.0])


def registered_with_noise(noise: float, seed: int) -> Uncertainty:
    model = bumpy_surface(5000)
    data = TRUTH.inverse().apply(model + np.random.default_rng(seed).normal(scale=noise, size=model.shape))
    result = register(data, model)
    assert result.uncertainty is not None
    return result.uncertainty


def test_sigmas_grow_with_the_noise() -> None:
    """Three times the noise (0.3 % to 0.9 % of the radius) on the same case: every sigma at
    least 1.5 times larger. (Per case, as the issue asks: the split halves' spread is a sample
    of three, so a quiet case's sigma may exceed another noisy case's.)"""
    for seed in (100, 101):
        quiet, noisy = registered_with_noise(0.003, seed), registered_with_noise(0.009, seed)
        for name in ("scale", "rotation_deg", "translation"):
            assert getattr(noisy, name) > 1.5 * getattr(quiet, name), (seed, name)


def test_noisy_samplings_of_one_surface_err_by_about_their_sigmas_in_every_block() -> None:
    """Eight independent noisy samplings of the bumpy surface, registered cold onto a ninth:
    every error within 3 of its sigmas, and the sigmas not inflated beyond need (the median
    error at least a third of a sigma in each block). Each block is widened by its own factor
    (refine.WIDENING, set on the real development scenes); here they give median ratios about
    0.8 (rotation), 0.55 (scale) and 0.7 (translation), the largest 1.8."""
    model = bumpy_surface(5000, seed=0)
    ratios = []
    for seed in range(100, 108):
        # The noise from a stream of its own: bumpy_surface(seed=seed) draws its directions from
        # default_rng(seed), and the same draws as noise would push every point outwards.
        noise = np.random.default_rng([seed, 1]).normal(scale=0.005, size=(3000, 3))
        data = TRUTH.inverse().apply(bumpy_surface(3000, seed=seed) + noise)
        result = register(data, model)
        assert result.reliable and result.uncertainty is not None
        centroid = data.mean(axis=0)
        errors = (
            np.degrees(rotation_angle(result.similarity.rotation @ TRUTH.rotation.T)),
            abs(np.log(result.similarity.scale / TRUTH.scale)),
            np.linalg.norm(result.similarity.apply(centroid) - TRUTH.apply(centroid)),
        )
        sigma = result.uncertainty
        ratios.append(np.divide(errors, (sigma.rotation_deg, sigma.scale, sigma.translation)))
    assert np.all(np.max(ratios, axis=0) <= 3.0)
    assert np.all(np.median(ratios, axis=0) >= 1.0 / 3.0)


def test_a_noise_free_copy_is_certain_to_far_below_the_tolerances() -> None:
    """Exact copies are registered exactly; the split-half spread (two different samplings of
    the surface) still says a little, which is the honest side to err on."""
    model = bumpy_surface(3000)
    result = register(TRUTH.inverse().apply(model), model)
    assert result.uncertainty is not None
    assert result.uncertainty.scale < 1e-4 and result.uncertainty.rotation_deg < 1e-2
    assert abs(np.log(result.similarity.scale / TRUTH.scale)) < 1e-9


def test_a_plane_leaves_its_sliding_directions_undetermined() -> None:
    """A flat patch fixes its normal offset and tilt but not a slide or a turn within the plane."""
    rng = np.random.default_rng(4)
    plane = np.column_stack([rng.uniform(-1, 1, (4000, 2)), rng.normal(scale=0.002, size=4000)])
    data = plane[:2000] + rng.normal(scale=0.002, size=(2000, 3))
    result = register(data, plane[2000:])
    assert result.uncertainty is not None
    surface = registered_with_noise(0.002, 100)
    assert result.uncertainty.translation > 30 * surface.translation


def test_an_undetermined_answer_states_the_prior_which_covers_every_plausible_pose() -> None:
    """Where the data do not determine the pose, 3 sigmas reach every rotation (180 deg), every
    plausible scale and every place the data's centroid may land with some of the data (0.1
    from its centroid, at most 20 times that in the model) in the model's box, whatever the
    answer was."""
    rng = np.random.default_rng(5)
    low, high = np.array([-1.0, -2.0, 0.0]), np.array([3.0, 1.0, 0.5])
    scales = (0.2, 20.0)
    answer = Similarity(0.5, axis_angle_rotation([1.0, 0.0, 0.0], 2.0), np.array([2.0, 0.0, 0.1]))
    centre = np.array([2.5, -1.5, 0.4])
    prior = Uncertainty.undetermined(answer, centre, scales, (low, high), data_reach=0.1)
    assert prior.rotation_deg == pytest.approx(60.0)
    assert prior.scale == pytest.approx(np.log(20.0 / 0.5) / 3)
    corner = np.linalg.norm([3.5, 2.5, 0.4])  # (-1, 1, 0)
    assert prior.translation == pytest.approx((corner + 20.0 * 0.1) / 3)
    for _ in range(200):
        landing = rng.uniform(low, high) + 20.0 * 0.1 * rng.uniform(-1, 1, 3) / np.sqrt(3)
        turn = np.degrees(rng.uniform(0.0, np.pi))
        scale = float(np.exp(rng.uniform(*np.log(scales))))
        assert turn <= 3 * prior.rotation_deg + 1e-9
        assert abs(np.log(scale / answer.scale)) <= 3 * prior.scale + 1e-9
        assert np.linalg.norm(landing - centre) <= 3 * prior.translation + 1e-9


def test_another_objects_answer_is_refused_with_the_prior_as_its_uncertainty() -> None:
    """A sphere registered onto the bumpy surface: no pose is right, and the result says it
    knows nothing (3 sigma: a half turn) instead of a local covariance about a random pose."""
    rng = np.random.default_rng(6)
    sphere = rng.normal(size=(3000, 3))
    sphere /= np.linalg.norm(sphere, axis=1, keepdims=True)
    result = register(sphere, bumpy_surface(3000))
    assert not result.reliable
    assert result.uncertainty is not None
    assert result.uncertainty.rotation_deg == pytest.approx(60.0)


def test_one_pose_gets_one_uncertainty_however_it_was_found():
    """The split halves draw from their own stream: a crop found cold by the descriptor search
    (many draws) and the same answer started warm (none) are given the same sigmas."""
    scene = bumpy_surface(6000, seed=3)
    crop = scene[scene[:, 0] < np.quantile(scene[:, 0], 0.4)]
    truth = Similarity(1.7, axis_angle_rotation(np.array([0.3, 1.0, 0.2]), 0.4), np.array([0.2, -0.1, 0.3]))
    cold = register(crop, truth.apply(scene))
    assert cold.reliable
    warm = register(crop, truth.apply(scene), RegistrationConfig(initial=cold.similarity))
    assert warm.uncertainty is not None and cold.uncertainty is not None
    assert warm.uncertainty.scale == pytest.approx(cold.uncertainty.scale, rel=0.05)
    assert warm.uncertainty.rotation_deg == pytest.approx(cold.uncertainty.rotation_deg, rel=0.05)
