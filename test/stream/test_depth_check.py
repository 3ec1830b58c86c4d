"""Coarse depth steps in a data stream are noticed, averaged out, reported with what to set, and
the advice goes once the settings average them: in the pipeline, /diagnostics and the bag mode."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from support.depth_camera import quantised, room_corner

from frisicp_core import Similarity
from frisicp_core.depth_steps import DepthSteps
from frisicp_ros.bag.output import pair_record
from frisicp_ros.bag.pairs import BagPair, StampedCloud
from frisicp_ros.bag.run import RunStats
from frisicp_ros.node.status import OK, WARN, NodeStatus
from frisicp_ros.stream.depth_check import (
    AVERAGE_STEPS,
    CHECK_EVERY,
    DepthStepCheck,
    averaged_by_settings,
    depth_step_advice,
)
from frisicp_ros.stream.outputs import rosbags_message_types
from frisicp_ros.stream.pipeline import Registered, RegistrationPipeline
from frisicp_ros.stream.pointcloud2 import points_to_parts
from frisicp_ros.stream.settings import settings_from

STEP = 0.06  # at 3 m: about 1.7 % of the room corner's size, a coarse camera


def on_shells(points: np.ndarray, step: float = STEP) -> np.ndarray:
    """``points`` as a depth camera reports them: z on disparity shells ``step`` apart at 3 m."""
    return quantised(points, step, "z", np.random.default_rng(0))


def message(points: np.ndarray, frame: str, stamp_ns: int):
    types = rosbags_message_types()
    return types.point_cloud(points_to_parts(points), types.header(stamp_ns, frame))


def test_the_check_looks_at_the_first_cloud_of_a_frame_then_every_hundredth():
    rng = np.random.default_rng(0)
    shelled, smooth = on_shells(room_corner(rng)), room_corner(rng)
    check = DepthStepCheck()
    assert check.look(shelled, "camera") is not None
    # The same sensor: the next clouds keep the finding, unlooked at...
    for _ in range(CHECK_EVERY - 1):
        assert check.look(smooth, "camera") is not None
    # ...until the hundredth after the last look, or a new frame.
    assert check.look(smooth, "camera") is None
    assert check.look(shelled, "camera") is None
    assert check.look(shelled, "other_camera") is not None
    check.reset()
    assert check.look(smooth, "other_camera") is None


def test_a_registered_pair_carries_the_finding_and_the_advice_works():
    rng = np.random.default_rng(1)
    model_points = room_corner(rng)
    data_points = on_shells(Similarity(1.0, np.eye(3), np.array([0.02, 0.0, 0.0])).apply(room_corner(rng)))
    pipeline = RegistrationPipeline(settings_from({"max_points": 3000}))
    outcome = pipeline.process(message(model_points, "map", 1), message(data_points, "camera", 2))
    assert isinstance(outcome, Registered)
    found = outcome.depth_steps
    assert found is not None and found.coarse and found.depth == "z"
    assert found.step == pytest.approx(STEP * (found.median_depth / 3.0) ** 2, rel=0.03)
    advice = outcome.depth_step_advice
    assert "voxel_mode: centroid" in advice and f"voxel_size >= {AVERAGE_STEPS * found.step:.3g}" in advice
    # Followed, the advice is not given again.
    pipeline.update_settings(
        replace(pipeline.settings, voxel_mode="centroid", voxel_size=AVERAGE_STEPS * found.step)
    )
    outcome = pipeline.process(message(model_points, "map", 3), message(data_points, "camera", 4))
    assert isinstance(outcome, Registered) and outcome.depth_step_advice == ""


def test_frames_of_a_coarse_camera_are_registered_averaged():
    # Two frames of one camera, both in its frame: terrace onto terrace they could lock, so the
    # core registers their averages over a step's voxels, unless the settings average them.
    rng = np.random.default_rng(3)
    first, second = (on_shells(room_corner(rng, 15_000)) for _ in range(2))
    pipeline = RegistrationPipeline(settings_from({"max_points": 5000}))
    outcome = pipeline.process(message(first, "camera", 1), message(second, "camera", 2))
    assert isinstance(outcome, Registered) and outcome.depth_steps is not None
    edge = AVERAGE_STEPS * outcome.depth_steps.step
    averaged = outcome.result.depth_averaged
    assert averaged is not None and averaged == pytest.approx((edge, edge), rel=0.05)
    assert outcome.data_points < 0.6 * 5000 and outcome.model_points < 0.5 * len(second)
    assert "registered as their averages" in outcome.depth_step_advice
    assert f"voxel_mode: centroid with voxel_size >= {edge:.3g}" in outcome.depth_step_advice
    _right_or_refused(outcome)
    # Averaged by the settings, before the cap: not again in the core, and no advice.
    pipeline.update_settings(replace(pipeline.settings, voxel_mode="centroid", voxel_size=edge))
    outcome = pipeline.process(message(first, "camera", 3), message(second, "camera", 4))
    assert isinstance(outcome, Registered) and outcome.result.depth_averaged is None
    assert outcome.depth_step_advice == "" and outcome.data_points < 5000
    _right_or_refused(outcome)
    # Switched off, the clouds are registered as read (and capped).
    pipeline.update_settings(
        replace(
            pipeline.settings,
            voxel_mode="first",
            voxel_size=0.0,
            registration=replace(pipeline.settings.registration, average_depth_steps=False),
        )
    )
    outcome = pipeline.process(message(first, "camera", 5), message(second, "camera", 6))
    assert isinstance(outcome, Registered) and outcome.result.depth_averaged is None
    assert outcome.data_points == 5000


def _right_or_refused(outcome: Registered) -> None:
    """Both frames sample one scene from one camera: the truth is the identity."""
    similarity = outcome.result.similarity
    if outcome.reliable:
        assert np.degrees(np.arccos(np.clip((np.trace(similarity.rotation) - 1) / 2, -1, 1))) < 1.0
        assert abs(similarity.scale - 1) < 0.01


def test_no_advice_for_fine_steps_nor_once_followed():
    coarse = DepthSteps("z", 0.06, 3.0, 0.017, 0.98, 30.0)
    assert depth_step_advice(coarse) != ""
    assert depth_step_advice(replace(coarse, step=0.01, share=0.003)) == ""
    assert depth_step_advice(None) == ""
    assert depth_step_advice(coarse, "centroid", AVERAGE_STEPS * 0.06) == ""
    assert depth_step_advice(coarse, "centroid", 0.5 * AVERAGE_STEPS * 0.06) != ""  # too small to help
    assert depth_step_advice(coarse, "first", AVERAGE_STEPS * 0.06) != ""  # a first point keeps them
    assert averaged_by_settings(coarse, "centroid", AVERAGE_STEPS * 0.06)
    assert not averaged_by_settings(coarse, "first", AVERAGE_STEPS * 0.06)
    assert not averaged_by_settings(None, "centroid", 1.0)


def _registered(depth_steps: DepthSteps | None) -> Registered:
    rng = np.random.default_rng(2)
    pipeline = RegistrationPipeline(settings_from({"max_points": 2000}))
    corner = room_corner(rng, 2000)
    outcome = pipeline.process(message(corner, "map", 1), message(corner, "camera", 2))
    assert isinstance(outcome, Registered) and outcome.reliable
    return replace(outcome, depth_steps=depth_steps, depth_step_advice=depth_step_advice(depth_steps))


COARSE = DepthSteps("z", 0.06, 3.0, 0.017, 0.98, 30.0)


def test_diagnostics_warn_with_the_advice_while_the_steps_are_coarse():
    status = NodeStatus()
    status.record(_registered(None), 0.1, 0.0)
    report = status.report(0, 0, True)
    assert report.level == OK and report.values["data depth steps"] == "none found"
    status.record(_registered(COARSE), 0.1, 0.0)
    report = status.report(0, 0, True)
    assert report.level == WARN and "voxel_mode: centroid" in report.message
    assert report.values["data depth steps"].startswith("depth steps of 0.06 at the median z 3")
    assert report.values["last depth averaged (data, model voxels)"] == "no"
    averaged = _registered(COARSE)
    status.record(replace(averaged, result=replace(averaged.result, depth_averaged=(0.06, 0.05))), 0.1, 0.0)
    assert status.report(0, 0, True).values["last depth averaged (data, model voxels)"] == "0.06, 0.05"
    status.record(_registered(None), 0.1, 0.0)  # averaged as advised
    assert status.report(0, 0, True).level == OK


def test_the_bag_mode_writes_the_steps_in_each_line_and_the_advice_in_its_summary():
    cloud = message(np.zeros((1, 3)), "camera", 2)
    pair = BagPair(0, StampedCloud(1, 0, cloud), StampedCloud(2, 0, cloud))
    assert "data_depth_steps" not in pair_record(pair, _registered(None))
    coarse = _registered(COARSE)
    record = pair_record(pair, coarse)
    assert record["data_depth_steps"] == {"depth": "z", "step": 0.06, "median_depth": 3.0, "share": 0.017}
    assert "depth_averaged" not in record
    averaged = replace(coarse, result=replace(coarse.result, depth_averaged=(0.06, 0.05)))
    assert pair_record(pair, averaged)["depth_averaged"] == [0.06, 0.05]
    stats = RunStats()
    stats.add(pair, _registered(None))
    assert "voxel_mode" not in stats.summary(0)
    stats.add(pair, coarse)
    stats.add(pair, _registered(None))
    assert stats.summary(0).endswith(coarse.depth_step_advice)
