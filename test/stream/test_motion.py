"""The constant-velocity warm start: prediction, stamp gaps, smoothing, resets, and the pipeline."""

from __future__ import annotations

import numpy as np
import pytest
from support.data import axis_rotation

from frisicp_core import Similarity, axis_angle_rotation, bumpy_surface
from frisicp_ros.stream.motion import MotionTracker, motion_of, velocity_of
from frisicp_ros.stream.outputs import rosbags_message_types
from frisicp_ros.stream.pipeline import Registered, RegistrationPipeline
from frisicp_ros.stream.pointcloud2 import points_to_parts
from frisicp_ros.stream.settings import PipelineSettings

MOUNT = Similarity(1.3, axis_rotation(3, 90.0), np.array([1.0, 2.0, 0.5]))
NS = 1_000_000_000


def pose(seconds: float) -> Similarity:
    """A sensor driving 0.5 m/s and turning 10 deg/s (a constant body velocity): model = P(t) S (data)."""
    turn = np.deg2rad(10.0) * seconds
    radius = 0.5 / np.deg2rad(10.0)
    moved = Similarity(
        1.0,
        axis_angle_rotation([0, 0, 1], turn),
        np.array([radius * np.sin(turn), radius * (1 - np.cos(turn)), 0.0]),
    )
    return moved @ MOUNT


def gap(a: Similarity, b: Similarity) -> tuple[float, float]:
    """(rotation in degrees, translation) between two similarities."""
    d = a.inverse() @ b
    return np.rad2deg(d.rotation_angle()), float(np.linalg.norm(d.translation))


def test_constant_velocity_is_predicted_exactly_and_missed_scans_are_bridged():
    tracker = MotionTracker()
    assert tracker.predict(0) is None
    first = pose(0.0)
    tracker.update(0, first)
    assert tracker.predict(NS // 10) is first  # one result: no velocity yet
    for k in range(1, 4):
        tracker.update(k * NS // 10, pose(k / 10))
    for ahead in (4, 5, 6):  # the next scan, and after one or two missed ones
        rotation, translation = gap(tracker.predict(ahead * NS // 10), pose(ahead / 10))
        # exact rotation; the translation is divided linearly: off by ~ angle x distance (0.3 mm)
        assert rotation < 1e-4 and translation < 1e-3
    np.testing.assert_array_equal(tracker.last.matrix(), pose(0.3).matrix())
    assert tracker.predict(3 * NS // 10 + 4 * NS // 10) is tracker.last  # a gap of 4 motions: no guess
    assert tracker.predict(3 * NS // 10) is tracker.last  # no time has passed


def test_scale_noise_is_not_extrapolated_and_velocity_noise_is_smoothed():
    rng = np.random.default_rng(0)
    tracker = MotionTracker()
    for k in range(40):  # a sensor at rest; estimates jitter (0.05 deg, 1 mm, 0.1 % scale)
        noise = Similarity(
            1.0 + 1e-3 * rng.normal(),
            axis_angle_rotation(rng.normal(size=3), np.deg2rad(0.05)),
            1e-3 * rng.normal(size=3),
        )
        tracker.update(k * NS // 10, MOUNT @ noise)
        start = tracker.predict((k + 1) * NS // 10)
        assert start.scale == pytest.approx(tracker.last.scale, rel=1e-12)  # the last scale, no trend
        rotation, translation = gap(start, MOUNT)
        assert rotation < 0.2 and translation < 0.006  # a raw extrapolation would double the jitter


def test_bad_stamps_and_wild_motion_fall_back_to_the_last_result():
    tracker = MotionTracker()
    tracker.update(5, pose(0.0))
    tracker.update(5, pose(0.1))  # same stamp (a bag without stamps): no velocity
    assert tracker.predict(10) is tracker.last
    tracker.update(10, pose(0.2))
    tracker.update(10 + NS, Similarity(1.3, axis_rotation(3, 150.0), np.zeros(3)))  # a 150 deg turn
    assert tracker.predict(10 + 2 * NS) is tracker.last
    tracker.reset()
    assert tracker.last is None and tracker.predict(0) is None


@pytest.mark.parametrize("dims", [2, 3])
def test_velocity_round_trip(dims):
    rotation = axis_rotation(dims, 12.0)
    motion = Similarity(1.0, rotation, np.arange(1.0, dims + 1.0))
    velocity = velocity_of(motion, 0.1)
    assert velocity is not None
    back = motion_of(velocity, 0.1, dims)
    np.testing.assert_allclose(back.rotation, rotation, atol=1e-12)
    np.testing.assert_allclose(back.translation, motion.translation, atol=1e-12)
    assert velocity_of(Similarity(1.0, np.eye(4), np.zeros(4)), 0.1) is None  # no axis above 3-D


def test_a_rotation_too_small_to_have_an_axis_is_no_rotation():
    # arccos of the trace reports ~1e-8 rad for a matrix a rounding away from the identity,
    # whose antisymmetric part (the axis) is exactly zero: the velocity must stay finite.
    nearly = np.eye(3) * (1 - 1e-16)
    nearly[0, 0] = 1 - 3e-16
    motion = Similarity(1.0, nearly, np.array([0.1, 0.0, 0.0]))
    velocity = velocity_of(motion, 0.1)
    assert velocity is not None
    assert np.all(np.isfinite(velocity.rotation))
    np.testing.assert_allclose(velocity.rotation, 0.0)


def moving_clouds(k: int, types=None):
    types = types or rosbags_message_types()
    surface = bumpy_surface(3000, seed=1)
    data = pose(k / 10).inverse().apply(surface)
    stamp = 7 * NS + k * NS // 10
    return (
        types.point_cloud(points_to_parts(surface), types.header(0, "map")),
        types.point_cloud(points_to_parts(data), types.header(stamp, "lidar")),
    )


def test_pipeline_warm_start_follows_a_moving_sensor_and_forgets_on_failure():
    pipeline = RegistrationPipeline(PipelineSettings.create())
    model = None
    for k in range(3):
        model_k, data = moving_clouds(k)
        model = model or model_k
        outcome = pipeline.process(model, data)
        assert isinstance(outcome, Registered) and outcome.reliable, outcome
    predicted = pipeline.warm_start_for(7 * NS + 3 * NS // 10)
    rotation, translation = gap(predicted, pose(0.3))
    assert rotation < 0.05 and translation < 0.005  # within the fit's noise of the next pose
    last_rotation, _ = gap(pipeline.previous, pose(0.3))
    assert last_rotation > 0.9  # the last result is a scan's turn (1 deg) behind
    still = RegistrationPipeline(PipelineSettings.create(motion_model="none"))
    still.process(model, moving_clouds(0)[1])
    still.process(model, moving_clouds(1)[1])
    assert still.warm_start_for(7 * NS + 2 * NS // 10) is still.previous
    types = rosbags_message_types()
    nan_cloud = types.point_cloud(points_to_parts(np.full((10, 3), np.nan)), types.header(0, "lidar"))
    pipeline.process(model, nan_cloud)
    assert pipeline.warm_start_for(8 * NS) is None  # a rejected pair: the next starts cold
    cold = RegistrationPipeline(PipelineSettings.create(warm_start=False))
    cold.process(model, moving_clouds(0)[1])
    assert cold.previous is not None and cold.warm_start_for(8 * NS) is None
