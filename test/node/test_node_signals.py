"""``register_node`` as a process under faults: repeated signals while busy, stamps that cannot be
normalised under rclpy's field checks, data without a model.

Domain 134 (unique to this module), loopback discovery only. The node is the console script in
its own session; signals go to its process group, as from a terminal or ``ros2 launch`` (which
forwards a second SIGINT after the terminal's own).
"""

from __future__ import annotations

import os
import signal
import subprocess
import time

import pytest
from support.ros import (
    TRUTH,
    ros_environment,
    scene_messages,
    spinning_node,
    transform_similarity,
    wait_until,
)
from support.scripts import installed_script

DOMAIN = 134
ENV = ros_environment(DOMAIN)

from geometry_msgs.msg import TransformStamped  # noqa: E402
from rclpy.qos import QoSProfile, ReliabilityPolicy  # noqa: E402
from sensor_msgs.msg import PointCloud2  # noqa: E402

pytestmark = pytest.mark.ros

REGISTER_NODE = installed_script("register_node")
RELIABLE = QoSProfile(depth=5, reliability=ReliabilityPolicy.RELIABLE)
TIMEOUT = 30.0


def start_node(*parameters: str, env: dict[str, str] | None = None) -> subprocess.Popen:
    command = [REGISTER_NODE, "--ros-args", "-p", "model_qos:=reliable", "-p", "data_qos:=reliable"]
    for parameter in parameters:
        command += ["-p", parameter]
    return subprocess.Popen(
        command,
        env=env or ENV,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
    )


def stop(process: subprocess.Popen) -> None:
    if process.poll() is None:
        os.killpg(process.pid, signal.SIGKILL)
        process.wait(5)


@pytest.fixture
def probe():
    with spinning_node("signal_probe", DOMAIN) as node:
        yield node


def publishers(probe):
    return (
        probe.create_publisher(PointCloud2, "model", RELIABLE),
        probe.create_publisher(PointCloud2, "data", RELIABLE),
    )


@pytest.mark.parametrize(
    "signals",
    [
        [signal.SIGINT, signal.SIGINT],  # used to exit -2 with a KeyboardInterrupt traceback
        [signal.SIGTERM, signal.SIGTERM],
        [signal.SIGINT, signal.SIGTERM, signal.SIGINT, signal.SIGINT],
    ],
    ids=["int-int", "term-term", "int-term-int-int"],
)
def test_repeated_signals_on_a_busy_node_exit_0_without_a_traceback(probe, signals):
    node = start_node("max_points:=0")  # full 20000-point clouds: always registering
    transforms: list[TransformStamped] = []
    probe.create_subscription(TransformStamped, "/frisicp/transform", transforms.append, 10)
    model_pub, data_pub = publishers(probe)
    model, data = scene_messages(20000)
    try:

        def feed() -> None:
            model_pub.publish(model)
            data_pub.publish(data)

        assert wait_until(lambda: bool(transforms), TIMEOUT, action=feed, every=0.2), "node never answered"
        for _ in range(5):  # keep it busy: a new pair is always pending
            feed()
        for signum in signals:
            os.killpg(node.pid, signum)
            time.sleep(0.05)
        try:
            _, stderr = node.communicate(timeout=20)
        except subprocess.TimeoutExpired:
            pytest.fail("register_node did not exit within 20 s of the signals")
        assert node.returncode == 0, stderr
        assert "Traceback" not in stderr and "KeyboardInterrupt" not in stderr, stderr
    finally:
        stop(node)


def test_a_stamp_that_cannot_be_normalised_is_passed_on_and_the_worker_survives(probe):
    """sec = 2^31 - 1 and nanosec = 2^32 - 1 overflowed the output's int32 sec: with
    ROS_PYTHON_CHECK_FIELDS=1 the publish raised and killed the worker for good; without it the
    stamp wrapped to 1901. The output now carries the stamp as received, and later pairs work."""
    node = start_node("max_points:=2000", env={**ENV, "ROS_PYTHON_CHECK_FIELDS": "1"})
    transforms: list[TransformStamped] = []
    probe.create_subscription(TransformStamped, "/frisicp/transform", transforms.append, 10)
    model_pub, data_pub = publishers(probe)
    model, data = scene_messages(2000)
    odd = scene_messages(2000)[1]
    odd.header.stamp.sec, odd.header.stamp.nanosec = 2**31 - 1, 2**32 - 1
    try:

        def stamps() -> set[tuple[int, int]]:
            return {(t.header.stamp.sec, t.header.stamp.nanosec) for t in transforms}

        def feed_odd() -> None:
            model_pub.publish(model)
            data_pub.publish(odd)

        assert wait_until(lambda: (2**31 - 1, 2**32 - 1) in stamps(), TIMEOUT, action=feed_odd, every=0.5), (
            node.poll(),
            stamps(),
        )
        wanted = (data.header.stamp.sec, data.header.stamp.nanosec)
        assert wait_until(
            lambda: wanted in stamps(), TIMEOUT, action=lambda: data_pub.publish(data), every=0.5
        )
        good = next(t for t in transforms if (t.header.stamp.sec, t.header.stamp.nanosec) == wanted)
        assert transform_similarity(good, TRUTH.scale).translation == pytest.approx(
            TRUTH.translation, abs=0.02
        )
        os.killpg(node.pid, signal.SIGINT)
        _, stderr = node.communicate(timeout=20)
        assert node.returncode == 0 and "Traceback" not in stderr, stderr
    finally:
        stop(node)


def test_data_without_a_model_logs_a_warning_naming_the_topic_and_the_qos_hint(probe):
    """A latched map missed by a volatile subscription left the node silent."""
    node = start_node()
    _, data_pub = publishers(probe)
    _, data = scene_messages(500)
    try:
        deadline = time.monotonic() + 10
        while time.monotonic() < deadline and probe.count_subscribers("/data") == 0:
            time.sleep(0.1)
        for _ in range(5):
            data_pub.publish(data)
            time.sleep(0.1)
        time.sleep(0.5)
        os.killpg(node.pid, signal.SIGINT)
        _, stderr = node.communicate(timeout=20)
    finally:
        stop(node)
    warnings = [line for line in stderr.splitlines() if "no model cloud has arrived" in line]
    assert warnings, stderr
    assert "'/model'" in warnings[0] and "model_qos: transient_local" in warnings[0]
    assert len(warnings) == 1, "the warning is throttled"
