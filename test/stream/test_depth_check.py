"""Coarse depth steps in a data stream are noticed, reported with what to do, and go away once
the clouds are averaged as advised: in the pipeline, the node's /diagnostics and the bag mode."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

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
    depth_step_advice,
    terrace_refusal,
)
from frisicp_ros.stream.outputs import rosbags_message_types
from frisicp_ros.stream.pipeline import Registered, RegistrationPipeline
from frisicp_ros.stream.pointcloud2 import points_to_parts
from frisicp_ros.stream.settings import settings_from

STEP = 0.06  # at 3 m: about 1.7 % of the room corner's size, a coarse camera


def room_corner(rng: np.random.Generator, n: int = 6000) -> np.ndarray:
    """A floor and two walls 2-4 m in front of a camera at the origin looking along +z."""
    u, v = rng.uniform(-1.0, 1.0, size=(2, n))
    part = rng.integers(0, 3, size=n)
    floor = np.column_stack([1.2 * u, np.full(n, 1.0), 3.0 + v])
    left = np.column_stack([-1.2 + 0.6 * (v + 1), 0.9 * u, 3.0 + 0.8 * v])
    right = np.column_stack([1.2 - 0.6 * (v + 1), 0.9 * u, 3.0 - 0.8 * v])
    corner: np.ndarray = np.choose(part[:, None], [floor, left, right])
    return corner


def on_shells(points: np.ndarray, step: float = STEP) -> np.ndarray:
    """``points`` as a depth camera reports them: z on disparity shells ``step`` apart at 3 m."""
    quantum = step / 9.0
    depth = 1.0 / (np.round(1.0 / points[:, 2] / quantum) * quantum)
    shelled: np.ndarray = points * (depth / points[:, 2])[:, None]
    return shelled


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


def test_frames_of_a_coarse_camera_are_not_called_reliable_until_averaged():
    # Two frames of one camera, both in its frame: the verdict cannot tell a terrace lock from a
    # fit, so the pipeline does not trust it. A map without steps as the model: it does (above).
    rng = np.random.default_rng(3)
    first, second = (on_shells(room_corner(rng, 15_000)) for _ in range(2))
    pipeline = RegistrationPipeline(settings_from({"max_points": 3000}))
    outcome = pipeline.process(message(first, "camera", 1), message(second, "camera", 2))
    assert isinstance(outcome, Registered) and not outcome.reliable
    assert outcome.reason.startswith("both clouds come in coarse depth steps (data: 0.0")
    assert "voxel_mode: centroid" in outcome.reason
    assert pipeline.previous is None  # nor tracked from
    step = outcome.depth_steps.step if outcome.depth_steps else 0.0
    pipeline.update_settings(
        replace(pipeline.settings, voxel_mode="centroid", voxel_size=AVERAGE_STEPS * step)
    )
    outcome = pipeline.process(message(first, "camera", 3), message(second, "camera", 4))
    assert isinstance(outcome, Registered) and not outcome.reason.startswith("both clouds")


def test_no_advice_for_fine_steps_nor_once_followed():
    coarse = DepthSteps("z", 0.06, 3.0, 0.017, 0.98, 30.0)
    assert depth_step_advice(coarse) != ""
    assert depth_step_advice(replace(coarse, step=0.01, share=0.003)) == ""
    assert depth_step_advice(None) == ""
    assert depth_step_advice(coarse, "centroid", AVERAGE_STEPS * 0.06) == ""
    assert depth_step_advice(coarse, "centroid", 0.5 * AVERAGE_STEPS * 0.06) != ""  # too small to help
    assert depth_step_advice(coarse, "first", AVERAGE_STEPS * 0.06) != ""  # a first point keeps them
    fine = replace(coarse, step=0.01, share=0.003)
    assert terrace_refusal(coarse, coarse, "first", 0.0) != ""
    assert terrace_refusal(coarse, fine, "first", 0.0) == terrace_refusal(coarse, None, "first", 0.0) == ""
    assert terrace_refusal(fine, coarse, "first", 0.0) == ""
    assert terrace_refusal(coarse, coarse, "centroid", AVERAGE_STEPS * 0.06) == ""


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
    status.record(_registered(None), 0.1, 0.0)  # averaged as advised
    assert status.report(0, 0, True).level == OK


def test_the_bag_mode_writes_the_steps_in_each_line_and_the_advice_in_its_summary():
    cloud = message(np.zeros((1, 3)), "camera", 2)
    pair = BagPair(0, StampedCloud(1, 0, cloud), StampedCloud(2, 0, cloud))
    assert "data_depth_steps" not in pair_record(pair, _registered(None))
    coarse = _registered(COARSE)
    record = pair_record(pair, coarse)
    assert record["data_depth_steps"] == {"depth": "z", "step": 0.06, "median_depth": 3.0, "share": 0.017}
    stats = RunStats()
    stats.add(pair, _registered(None))
    assert "voxel_mode" not in stats.summary(0)
    stats.add(pair, coarse)
    stats.add(pair, _registered(None))
    assert stats.summary(0).endswith(coarse.depth_step_advice)
