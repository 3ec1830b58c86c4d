"""Initial guesses: RViz's pose (and the command line's) become the core's InitialGuess, and the
pipeline searches around one for the next pair, then tracks from that result."""

from __future__ import annotations

import math

import numpy as np
import pytest
from support.guess_scene import guess_covariance, right_and_reliable, symmetric_scene_clouds

from frisicp_core import Similarity, axis_angle_rotation
from frisicp_ros.stream.guess import KNOWN_SCALE_SIGMA, guess_from_pose, parse_initial
from frisicp_ros.stream.outputs import rosbags_message_types
from frisicp_ros.stream.pipeline import Registered, RegistrationPipeline
from frisicp_ros.stream.settings import PipelineSettings

# RViz's "2D Pose Estimate": 0.25 on x and y, pi^2/144 (15 degrees squared) on yaw, zeros elsewhere.
RVIZ_COVARIANCE = np.zeros(36)
RVIZ_COVARIANCE[[0, 7]] = 0.25
RVIZ_COVARIANCE[35] = 0.06853891945200942


def yaw_quaternion(degrees: float) -> list[float]:
    half = math.radians(degrees) / 2
    return [0.0, 0.0, math.sin(half), math.cos(half)]


def test_rviz_2d_pose_estimate_gives_half_a_metre_and_fifteen_degrees():
    guess = guess_from_pose([1.0, 2.0, 0.0], yaw_quaternion(90.0), RVIZ_COVARIANCE, dims=3)
    assert guess.translation == pytest.approx(0.5)
    assert guess.rotation_deg == pytest.approx(15.0, rel=1e-6)
    assert guess.scale is None  # unknown: searched
    np.testing.assert_allclose(guess.similarity.translation, [1.0, 2.0, 0.0])
    np.testing.assert_allclose(
        guess.similarity.rotation, axis_angle_rotation([0, 0, 1], math.pi / 2), atol=1e-12
    )
    planar = guess_from_pose([1.0, 2.0, 0.0], yaw_quaternion(90.0), RVIZ_COVARIANCE, dims=2, scale=2.5)
    np.testing.assert_allclose(planar.similarity.rotation, [[0.0, -1.0], [1.0, 0.0]], atol=1e-12)
    assert (planar.similarity.scale, planar.scale) == (2.5, KNOWN_SCALE_SIGMA)
    np.testing.assert_allclose(planar.similarity.translation, [1.0, 2.0])


def test_the_largest_eigenvalue_of_each_block_is_the_sigma():
    covariance = np.zeros((6, 6))
    covariance[:3, :3] = [[1.0, 0.9, 0.0], [0.9, 1.0, 0.0], [0.0, 0.0, 0.1]]  # largest eigenvalue 1.9
    covariance[3:, 3:] = np.diag([0.0, math.radians(3.0) ** 2, 0.0])
    guess = guess_from_pose([0, 0, 0], [0, 0, 0, 1], covariance.reshape(-1), dims=3)
    assert guess.translation == pytest.approx(math.sqrt(1.9))
    assert guess.rotation_deg == pytest.approx(3.0)


@pytest.mark.parametrize(
    ("position", "orientation", "covariance", "reason"),
    [
        ([0, 0, math.nan], [0, 0, 0, 1], np.zeros(36), "NaN or infinite"),
        ([0, 0, 0], [0, 0, 0, 0], np.zeros(36), "zero quaternion"),
        ([0, 0, 0], [0, 0, 0, 1], -np.eye(6).reshape(-1), "negative variance"),
        ([0, 0, 0], [0, 0, 0, 1], np.full(36, math.inf), "NaN or infinite"),
        ([0, 0, 0], [0, 0, 0, 1], np.zeros(35), "36 values"),
    ],
)
def test_unusable_guesses_are_refused_with_the_reason(position, orientation, covariance, reason):
    with pytest.raises(ValueError, match=reason):
        guess_from_pose(position, orientation, covariance, dims=3)


def test_command_line_form():
    guess = parse_initial("1 2 3 0 0 0 1 2.0", "5,0.25", dims=3)
    assert (guess.rotation_deg, guess.translation, guess.scale) == pytest.approx((5.0, 0.25, 0.01))
    assert guess.similarity.scale == 2.0
    assert parse_initial("1 2 3 0 0 0 1", "5,0.25,0.1", dims=3).scale is None  # no scale: unknown
    assert parse_initial("1 2 3 0 0 0 1 3", "5,0.25,0.1", dims=3).scale == pytest.approx(0.1)
    for pose, sigma, reason in [
        ("1 2 3", "5,0.25", "7 or 8 numbers"),
        ("1 2 3 0 0 0 one", "5,0.25", "takes numbers"),
        ("1 2 3 0 0 0 1", None, "needs --initial-sigma"),
        ("1 2 3 0 0 0 1", "5", "2 or 3 numbers"),
        ("1 2 3 0 0 0 1 -2", "5,1", "scale must be positive"),
    ]:
        with pytest.raises(ValueError, match=reason):
            parse_initial(pose, sigma, dims=3)


def rotation_error_deg(estimate: Similarity, truth: Similarity) -> float:
    return math.degrees((estimate @ truth.inverse()).rotation_angle())


def test_a_guess_steers_the_next_pair_that_no_blind_search_can_answer_and_tracking_follows():
    model, (first, second, third), truth, rough = symmetric_scene_clouds(rosbags_message_types())
    settings = PipelineSettings.create(max_points=0)
    blind = RegistrationPipeline(settings).process(model, first)
    assert isinstance(blind, Registered)
    assert not right_and_reliable(rotation_error_deg(blind.result.similarity, truth), blind.reliable)

    pipeline = RegistrationPipeline(settings)
    pipeline.guess_next(guess_from_pose(rough.translation, rough.quaternion(), guess_covariance(), dims=3))
    guided = pipeline.process(model, first)
    assert isinstance(guided, Registered) and guided.reliable and not guided.warm_started
    assert rotation_error_deg(guided.result.similarity, truth) < 0.5
    assert guided.result.similarity.scale == pytest.approx(2.0, rel=0.01)
    assert pipeline.guess is None  # used up by that one registration
    # The pairs after it track from the guided result (a warm start), and stay right.
    for later in (second, third):
        tracked = pipeline.process(model, later)
        assert isinstance(tracked, Registered) and tracked.warm_started
        assert rotation_error_deg(tracked.result.similarity, truth) < 0.5
