"""The node's ROS-free parts: the newest-wins hand-over and the diagnostics bookkeeping."""

from __future__ import annotations

import threading
import time

import numpy as np
import pytest

from frisicp_core import bumpy_surface
from frisicp_ros.node.newest_slot import NewestWinsSlot
from frisicp_ros.node.status import ERROR, OK, WARN, NodeStatus
from frisicp_ros.stream.outputs import rosbags_message_types
from frisicp_ros.stream.pipeline import RegistrationPipeline
from frisicp_ros.stream.pointcloud2 import points_to_parts


def test_slot_keeps_the_newest_and_counts_the_dropped_oldest():
    slot: NewestWinsSlot[int] = NewestWinsSlot()
    assert slot.put(1) is False
    assert slot.put(2) is True and slot.put(3) is True
    assert slot.dropped == 2 and slot.pending == 1
    assert slot.take(timeout=0) == 3
    assert slot.take(timeout=0.01) is None
    slot.put(4)
    slot.clear()
    assert slot.take(timeout=0) is None and slot.dropped == 2  # a reset is not an overload


def test_slot_close_wakes_a_waiting_taker_at_once():
    slot: NewestWinsSlot[int] = NewestWinsSlot()
    result: list[object] = []
    taker = threading.Thread(target=lambda: result.append(slot.take(timeout=30)))
    taker.start()
    time.sleep(0.05)
    started = time.monotonic()
    slot.close()
    taker.join(5)
    assert result == [None] and time.monotonic() - started < 1.0
    slot.put(5)
    assert slot.take(timeout=0) is None


def _outcomes():
    types = rosbags_message_types()
    points = bumpy_surface(600, seed=2)
    model = types.point_cloud(points_to_parts(points * 2.0), types.header(1, "map"))
    data = types.point_cloud(points_to_parts(points), types.header(2, "lidar"))
    nan = types.point_cloud(points_to_parts(np.full((10, 3), np.nan)), types.header(3, "lidar"))
    pipeline = RegistrationPipeline()
    return pipeline.process(model, data), pipeline.process(model, nan)


def test_status_levels_counters_and_latency():
    good, bad = _outcomes()
    status = NodeStatus()
    report = status.report(dropped_pairs=0, unpaired_data=0, has_model=False)
    assert report.level == WARN and "model" in report.message
    status.count_input("model")
    status.count_input("data", transport=0.02, callback=0.003)
    status.record(good, latency=0.25, publish_seconds=0.001)
    report = status.report(dropped_pairs=4, unpaired_data=1, has_model=True)
    assert report.level == OK
    timings = good.timings
    assert float(report.values["output mean (ms)"]) == 1.0
    assert float(report.values["registration mean (ms)"]) == pytest.approx(
        timings.register_seconds * 1e3, abs=0.1
    )
    overhead = (timings.convert_seconds + timings.downsample_seconds + 0.001) / timings.register_seconds
    # the report prints four decimals, so it matches to half a unit of the last one
    assert float(report.values["node overhead / registration"]) == pytest.approx(overhead, abs=5e-5)
    assert (report.values["data transport p50 (ms)"], report.values["callback delay max (ms)"]) == (
        "20.0",
        "3.00",
    )
    assert report.values["dropped pairs"] == "4" and report.values["registered pairs"] == "1"
    assert float(report.values["latency p50 (ms)"]) == 250.0
    assert float(report.values["data rate (Hz)"]) > 0 and report.values["last converged"] == "True"
    status.record(bad, None, 0.0)
    report = status.report(4, 1, True)
    assert report.level == WARN and "no finite points" in report.message
    assert report.values["rejected data clouds"] == "1"
    status.record(bad, None, 0.0)
    status.record(bad, None, 0.0)
    assert status.report(4, 1, True).level == ERROR
    status.record(good, 0.1, 0.0)
    assert status.report(4, 1, True).level == OK


def _implausible(outcome):
    """``outcome`` with a result the verdict refuses (as a garbage cloud produces)."""
    import dataclasses

    from frisicp_core import Similarity

    result = dataclasses.replace(
        outcome.result,
        similarity=Similarity(1.5e40, np.eye(3), np.zeros(3)),
        reliable=False,
        reason="scale 1.5e+40 is far from the clouds' size ratio",
    )
    return dataclasses.replace(outcome, result=result)


def test_status_is_never_ok_for_an_implausible_result():
    good, _ = _outcomes()
    status = NodeStatus()
    status.record(good, 0.1, 0.0)
    assert status.report(0, 0, True).level == OK
    status.record(_implausible(good), None, 0.0)
    report = status.report(0, 0, True)
    assert report.level == WARN and "implausible" in report.message and "1.5e+40" in report.message
    assert report.values["unreliable results"] == "1" and report.values["registered pairs"] == "1"
    assert report.values["last scale"] == f"{good.result.similarity.scale:.6g}"  # the last *published* one
    status.record(_implausible(good), None, 0.0)
    status.record(_implausible(good), None, 0.0)
    assert status.report(0, 0, True).level == ERROR
    status.record(good, 0.1, 0.0)
    assert status.report(0, 0, True).level == OK


def test_publish_errors_are_counted_and_a_stopped_worker_is_an_error():
    good, _ = _outcomes()
    status = NodeStatus()
    status.record(good, 0.1, 0.0)
    status.record_error("AssertionError: the 'sec' field must be an integer")
    report = status.report(0, 0, True)
    assert report.level == WARN and report.values["publish errors"] == "1"
    assert "sec" in report.values["last publish error"]
    status.record(good, 0.1, 0.0)
    assert status.report(0, 0, True).level == OK
    status.record_worker_stopped("RuntimeError: boom")
    status.record(good, 0.1, 0.0)  # nothing said before the worker died makes it OK again
    report = status.report(0, 0, True)
    assert report.level == ERROR and "worker stopped" in report.message and "boom" in report.message
