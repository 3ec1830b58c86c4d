"""The node as users start it: the ``register_node`` console script in its own process.

Domain 132 (unique to this module), loopback discovery only. Checks remapping, --params-file,
a latched (transient-local) model, the published transform against the known similarity,
parameter validation through the real SetParameters service, and a clean SIGINT exit.
"""

from __future__ import annotations

import signal
import subprocess
from pathlib import Path

import numpy as np
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

DOMAIN = 132
ENV = ros_environment(DOMAIN)

from geometry_msgs.msg import TransformStamped, Vector3Stamped  # noqa: E402
from rcl_interfaces.srv import SetParameters  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy  # noqa: E402
from sensor_msgs.msg import PointCloud2  # noqa: E402

pytestmark = pytest.mark.ros

ROOT = Path(__file__).resolve().parents[2]
REGISTER_NODE = installed_script("register_node")
LATCHED = QoSProfile(
    depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL
)
TIMEOUT = 30.0


@pytest.fixture
def node_process():
    command = [
        str(REGISTER_NODE),
        "--ros-args",
        "--params-file",
        str(ROOT / "config" / "frisicp.yaml"),
        "-p",
        "model_qos:=transient_local",
        "-p",
        "max_points:=3000",
        "-r",
        "model:=/test/map",
        "-r",
        "data:=/test/scan",
    ]
    process = subprocess.Popen(command, env=ENV, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    yield process
    if process.poll() is None:
        process.kill()
        process.wait(5)


@pytest.fixture
def probe():
    with spinning_node("process_probe", DOMAIN) as node:
        yield node


def test_console_script_registers_validates_parameters_and_exits_cleanly_on_sigint(node_process, probe):
    transforms: list[TransformStamped] = []
    scales: list[Vector3Stamped] = []
    probe.create_subscription(TransformStamped, "/frisicp/transform", transforms.append, 10)
    probe.create_subscription(Vector3Stamped, "/frisicp/scale", scales.append, 10)
    model_pub = probe.create_publisher(PointCloud2, "/test/map", LATCHED)
    data_pub = probe.create_publisher(PointCloud2, "/test/scan", 10)
    model, data = scene_messages()
    model_pub.publish(model)  # once: the node's transient-local subscription gets it when it appears

    assert wait_until(lambda: bool(transforms), TIMEOUT, action=lambda: data_pub.publish(data), every=0.5), (
        "no transform from the node process: " + _stderr_if_dead(node_process)
    )
    transform = transforms[0]
    assert (transform.header.frame_id, transform.child_frame_id) == ("map", "velodyne")
    assert transform.header.stamp == data.header.stamp  # the data's stamp, not now()
    assert wait_until(lambda: bool(scales), 5.0)
    estimate = transform_similarity(transform, scales[0].vector.x)
    assert estimate.scale == pytest.approx(TRUTH.scale, rel=1e-3)
    np.testing.assert_allclose(estimate.rotation, TRUTH.rotation, atol=3e-3)
    np.testing.assert_allclose(estimate.translation, TRUTH.translation, atol=1e-2)

    # `ros2 param set /frisicp overlap 1.5` goes through this service
    client = probe.create_client(SetParameters, "/frisicp/set_parameters")
    assert client.wait_for_service(timeout_sec=TIMEOUT)
    request = SetParameters.Request(
        parameters=[
            Parameter("overlap", value=1.5).to_parameter_msg(),
            Parameter("levels", value=2).to_parameter_msg(),
        ]
    )
    future = client.call_async(request)
    assert wait_until(future.done, TIMEOUT)
    overlap_result, levels_result = future.result().results
    assert not overlap_result.successful and "overlap" in overlap_result.reason
    assert levels_result.successful

    node_process.send_signal(signal.SIGINT)
    try:
        _, stderr = node_process.communicate(timeout=15)
    except subprocess.TimeoutExpired:
        node_process.kill()
        pytest.fail("register_node did not exit within 15 s of SIGINT")
    assert node_process.returncode == 0, stderr
    assert "Traceback" not in stderr, stderr


@pytest.mark.parametrize("script", ["register_node", "register_lifecycle_node"])
def test_invalid_parameter_file_value_fails_with_a_message(tmp_path, script):
    bad = tmp_path / "bad.yaml"
    bad.write_text("/**:\n  ros__parameters:\n    overlap: 1.5\n")
    run = subprocess.run(
        [str(installed_script(script)), "--ros-args", "--params-file", str(bad)],
        env=ENV,
        capture_output=True,
        text=True,
        timeout=30,
    )
    assert run.returncode == 2
    assert "invalid parameters" in run.stderr and "overlap" in run.stderr and "Traceback" not in run.stderr


def _stderr_if_dead(process: subprocess.Popen) -> str:
    if process.poll() is None:
        return "(still running)"
    return process.stderr.read() if process.stderr else ""
