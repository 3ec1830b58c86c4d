"""register_node replaying a bag (``bag`` parameter), with real rclpy on loopback in domain 207.

The node runs as users start it (the console script, its own process); a probe node in this
process subscribes to its outputs and checks the transforms against the bag's known similarities.
"""

from __future__ import annotations

import os
import signal
import subprocess
import threading
import time
from pathlib import Path

import numpy as np
import pytest
import rclpy
from geometry_msgs.msg import TransformStamped, Vector3Stamped
from rclpy.executors import SingleThreadedExecutor
from rclpy.qos import QoSProfile, ReliabilityPolicy
from support.bags import DATA_FRAME, DATA_TOPIC, MODEL_FRAME, MODEL_TOPIC, standard_scenario, write_rosbag2
from support.ros import wait_until
from support.scripts import installed_script

from frisicp_core import Similarity, rotation_angle

pytestmark = pytest.mark.ros

# Set per test (fixture), not at import: other modules' import-time settings must not leak in or out.
ROS_SETTINGS = {"ROS_DOMAIN_ID": "207", "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"}
ENV = {**{k: v for k, v in os.environ.items() if k != "ROS_STATIC_PEERS"}, **ROS_SETTINGS}

REGISTER_NODE = installed_script("register_node")
TIMEOUT = 40.0


@pytest.fixture(scope="module")
def scenario():
    return standard_scenario(800)


@pytest.fixture(scope="module")
def bag(tmp_path_factory, scenario) -> Path:
    return write_rosbag2(tmp_path_factory.mktemp("replay") / "recording", scenario.records, "mcap")


class OutputProbe:
    """A node in this process recording the replaying node's transforms and scales."""

    def __init__(self) -> None:
        self.transforms: list[TransformStamped] = []
        self.scales: list[Vector3Stamped] = []
        self.arrivals: list[float] = []  # time.monotonic() of each transform
        self.context = rclpy.Context()
        rclpy.init(context=self.context)
        self.node = rclpy.create_node("replay_probe", context=self.context)
        reliable = QoSProfile(depth=50, reliability=ReliabilityPolicy.RELIABLE)
        self.node.create_subscription(TransformStamped, "/frisicp/transform", self._on_transform, reliable)
        self.node.create_subscription(Vector3Stamped, "/frisicp/scale", self.scales.append, reliable)
        self._executor = SingleThreadedExecutor(context=self.context)
        self._executor.add_node(self.node)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._spin, daemon=True)
        self._thread.start()

    def _on_transform(self, msg: TransformStamped) -> None:
        self.arrivals.append(time.monotonic())
        self.transforms.append(msg)

    def _spin(self) -> None:
        while not self._stop.is_set():
            self._executor.spin_once(timeout_sec=0.1)

    def close(self) -> None:
        self._stop.set()
        self._thread.join(5)
        self.node.destroy_node()
        self.context.try_shutdown()


@pytest.fixture
def probe(monkeypatch):
    for name, value in ROS_SETTINGS.items():
        monkeypatch.setenv(name, value)  # rclpy.init reads them
    monkeypatch.delenv("ROS_STATIC_PEERS", raising=False)
    probe = OutputProbe()
    yield probe
    probe.close()


def start_node(bag: Path, *parameters: str) -> subprocess.Popen:
    command = [
        str(REGISTER_NODE),
        "--ros-args",
        "-r",
        f"model:={MODEL_TOPIC}",
        "-r",
        f"data:={DATA_TOPIC}",
        "-p",
        f"bag:={bag}",
        "-p",
        "warm_start:=false",
        "-p",
        "bag_wait_for_subscribers:=1",
    ]
    for parameter in parameters:
        command += ["-p", parameter]
    return subprocess.Popen(command, env=ENV, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def finish(process: subprocess.Popen) -> tuple[int, str]:
    try:
        _, err = process.communicate(timeout=TIMEOUT)
    except subprocess.TimeoutExpired:
        process.kill()
        _, err = process.communicate(timeout=5)
        pytest.fail(f"register_node did not exit: {err}")
    return process.returncode, err


def assert_transforms_match(transforms, scales, scenario) -> None:
    data = scenario.data_records()
    assert [m.header.stamp.sec * 10**9 + m.header.stamp.nanosec for m in transforms] == [
        d.header_ns for d in data
    ]
    for msg, scale, record in zip(transforms, scales, data, strict=False):
        assert (msg.header.frame_id, msg.child_frame_id) == (MODEL_FRAME, DATA_FRAME)
        q, t = msg.transform.rotation, msg.transform.translation
        estimate = Similarity.from_quaternion(scale.vector.x, [q.x, q.y, q.z, q.w], [t.x, t.y, t.z])
        truth = scenario.truth[record.bag_ns]
        assert estimate.scale == pytest.approx(truth.scale, rel=5e-3)
        assert np.degrees(rotation_angle(estimate.rotation.T @ truth.rotation)) < 0.5
        np.testing.assert_allclose(estimate.translation, truth.translation, atol=0.01 * truth.scale + 0.005)


def test_replay_as_fast_as_possible_publishes_every_pair_then_exits(bag, scenario, probe):
    process = start_node(bag, "bag_rate:=0.0", "bag_delay:=0.5")
    code, err = finish(process)
    assert code == 0, err
    assert "bag replay done: 4 pairs" in err
    assert wait_until(lambda: len(probe.transforms) == 4 and len(probe.scales) == 4, 5.0), (
        f"{len(probe.transforms)} transforms, {len(probe.scales)} scales; node log: {err}"
    )
    assert_transforms_match(probe.transforms, probe.scales, scenario)


def test_replay_at_recorded_rate_then_idles_until_interrupted(bag, scenario, probe):
    process = start_node(bag, "bag_rate:=1.0", "bag_delay:=0.5", "bag_exit_on_end:=false")
    try:
        assert wait_until(lambda: len(probe.transforms) == 4, TIMEOUT), "no transforms"
        # The data clouds were recorded over 2 s (1.005 ... 3.005 s): the replay takes as long.
        arrivals = probe.arrivals
        assert 1.9 <= arrivals[-1] - arrivals[0] < 4.0
        assert process.poll() is None, "the node must stay up (idle) after the bag"
        time.sleep(1.0)
        assert process.poll() is None
    finally:
        process.send_signal(signal.SIGINT)
    code, err = finish(process)
    assert code == 0, err
    assert_transforms_match(probe.transforms, probe.scales, scenario)


def test_replay_of_an_unusable_bag_fails_at_start_up_with_the_reason(tmp_path, bag):
    code, err = finish(start_node(tmp_path / "missing.mcap"))
    assert code == 2 and "missing.mcap: no such file or directory" in err and "Traceback" not in err
    wrong_topic = subprocess.Popen(
        [str(REGISTER_NODE), "--ros-args", "-r", "model:=/nothing", "-p", f"bag:={bag}"],
        env=ENV,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    code, err = finish(wrong_topic)
    assert code == 2 and "/nothing is not in the bag" in err and MODEL_TOPIC in err and "Traceback" not in err
