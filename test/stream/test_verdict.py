"""The plausibility verdict in the shared pipeline: no silent wrong answer, no poisoned warm start.

A cloud can parse and still be garbage (little-endian bytes flagged big-endian give values like
1e-39 or NaN). Whatever it yields, it must never be passed on as a pose nor steer the pairs
after it. Written against behaviour, not against the core's thresholds.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from support.data import with_absurd_scale

from frisicp_core import Similarity, axis_angle_rotation, bumpy_surface, rotation_angle
from frisicp_ros.stream import pipeline as pipeline_module
from frisicp_ros.stream.outputs import OUTPUT_TOPICS, build_outputs, rosbags_message_types
from frisicp_ros.stream.pipeline import Registered, RegistrationPipeline, Rejected
from frisicp_ros.stream.pointcloud2 import points_to_parts
from frisicp_ros.stream.settings import PipelineSettings

TRUTH = Similarity(1.5, axis_angle_rotation([0.3, 1.0, 0.2], np.deg2rad(20.0)), np.array([0.5, -1.0, 2.0]))
TYPES = rosbags_message_types()
DATA = bumpy_surface(400, seed=11)


def cloud(points, frame: str = "lidar", stamp: tuple[int, int] = (2, 0), big_endian_flag: bool = False):
    parts = points_to_parts(points)
    if big_endian_flag:  # the bytes stay little-endian: the flag lies
        parts = dataclasses.replace(parts, is_bigendian=True)
    return TYPES.point_cloud(parts, TYPES.stamped_header(stamp, frame))


MODEL = cloud(TRUTH.apply(DATA), "map", (1, 0))
GOOD = cloud(DATA)
GARBAGE = cloud(DATA, big_endian_flag=True)
MALFORMED = dataclasses.replace(GOOD, row_step=GOOD.row_step - 1)


def assert_correct(outcome) -> None:
    assert isinstance(outcome, Registered) and outcome.reliable, outcome
    estimate = outcome.result.similarity
    assert estimate.scale == pytest.approx(TRUTH.scale, rel=1e-2)
    assert np.degrees(rotation_angle(estimate.rotation.T @ TRUTH.rotation)) < 1.0


def test_a_garbage_cloud_is_never_ok_and_never_becomes_the_warm_start():
    pipeline = RegistrationPipeline(PipelineSettings.create())
    assert_correct(pipeline.process(MODEL, GOOD))
    assert pipeline.previous is not None
    garbage = pipeline.process(MODEL, GARBAGE)
    assert isinstance(garbage, Rejected) or not garbage.reliable, garbage
    if isinstance(garbage, Registered):
        assert garbage.reason  # says why it is not believed
        with pytest.raises(ValueError, match="unreliable"):
            build_outputs(garbage, GARBAGE, TYPES)  # no topic, no result bag entry
    assert pipeline.previous is None, "an implausible result must not be the next warm start"
    after = pipeline.process(MODEL, GOOD)
    assert_correct(after)
    assert not after.warm_started  # started cold, from nothing the garbage left behind


def test_every_rejection_clears_the_warm_start():
    """docs/node.md: a rejected pair clears the warm start (a malformed cloud did not)."""
    pipeline = RegistrationPipeline(PipelineSettings.create())
    for bad_model, bad_data in (
        (MODEL, MALFORMED),
        (MALFORMED, GOOD),
        (MODEL, cloud(np.full((9, 3), np.nan))),
    ):
        assert_correct(pipeline.process(MODEL, GOOD))
        assert pipeline.previous is not None
        assert isinstance(pipeline.process(bad_model, bad_data), Rejected)
        assert pipeline.previous is None


def test_an_unexpected_exception_is_a_rejected_pair_not_a_crash(monkeypatch):
    pipeline = RegistrationPipeline(PipelineSettings.create())
    assert_correct(pipeline.process(MODEL, GOOD))

    def broken(*args, **kwargs):
        raise RuntimeError("a bug in the core")

    monkeypatch.setattr(pipeline_module, "register", broken)
    outcome = pipeline.process(MODEL, GOOD)
    assert isinstance(outcome, Rejected) and "RuntimeError: a bug in the core" in outcome.reason
    assert pipeline.previous is None


def test_a_result_carries_its_verdict_and_only_a_reliable_one_has_outputs():
    outcome = RegistrationPipeline().process(MODEL, GOOD)
    assert isinstance(outcome, Registered) and outcome.reliable and outcome.reason == ""
    assert 0 < outcome.result.overlap_forward <= 1 and 0 < outcome.result.overlap_backward <= 1
    assert set(build_outputs(outcome, GOOD, TYPES, tuple(OUTPUT_TOPICS))) == set(OUTPUT_TOPICS)
    implausible = with_absurd_scale(outcome)
    with pytest.raises(ValueError, match="unreliable result has no outputs"):
        build_outputs(implausible, GOOD, TYPES, tuple(OUTPUT_TOPICS))


def test_outputs_copy_the_data_stamp_as_received_even_when_it_is_not_normalised():
    """sec = 2^31 - 1 with nanosec >= 1e9 cannot be normalised into a 32-bit sec: it must not
    wrap (nor raise in rclpy's field checks); it is passed on as it came."""
    stamp = (2**31 - 1, 2**32 - 1)
    data = cloud(DATA, stamp=stamp)
    outcome = RegistrationPipeline().process(MODEL, data)
    assert isinstance(outcome, Registered) and outcome.stamp == stamp
    assert outcome.stamp_ns == (2**31 - 1) * 10**9 + 2**32 - 1
    for message in build_outputs(outcome, data, TYPES, tuple(OUTPUT_TOPICS)).values():
        if hasattr(message, "header"):
            assert (message.header.stamp.sec, message.header.stamp.nanosec) == stamp


def test_a_pair_past_the_registration_budget_is_unreliable_and_clears_the_warm_start():
    """budget_seconds (node parameter, frisicp bag --budget-seconds): no cloud holds the worker
    longer; the result says why it is not believed and is not the next warm start."""
    pipeline = RegistrationPipeline(PipelineSettings.create())
    assert pipeline.settings.registration.budget_seconds == 15.0  # the stream's default
    assert_correct(pipeline.process(MODEL, GOOD))
    pipeline.update_settings(pipeline.settings.updated(budget_seconds=1e-9))
    outcome = pipeline.process(MODEL, GOOD)
    assert isinstance(outcome, Registered) and not outcome.reliable
    assert outcome.reason.startswith("budget exceeded: stopped after")
    assert pipeline.previous is None
    pipeline.update_settings(pipeline.settings.updated(budget_seconds=0.0))  # 0 = unbounded
    assert pipeline.settings.registration.budget_seconds is None
    assert_correct(pipeline.process(MODEL, GOOD))
