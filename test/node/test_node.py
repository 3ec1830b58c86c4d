"""The node in-process: node + test publisher/subscriber in one executor on a thread, real DDS.

Domain 131 (unique to this module), loopback discovery only.
"""

from __future__ import annotations

import threading
import time

import numpy as np
import pytest
from support.ros import (
    TRUTH,
    cloud_message,
    ros_environment,
    scene_messages,
    transform_similarity,
    wait_until,
)

DOMAIN = 131
ros_environment(DOMAIN)

import rclpy  # noqa: E402
from diagnostic_msgs.msg import DiagnosticArray  # noqa: E402
from geometry_msgs.msg import PoseWithCovarianceStamped, TransformStamped, Vector3Stamped  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from rclpy.qos import QoSProfile, ReliabilityPolicy  # noqa: E402
from sensor_msgs.msg import PointCloud2  # noqa: E402
from std_msgs.msg import Float64MultiArray  # noqa: E402
from std_srvs.srv import Trigger  # noqa: E402

from frisicp_core import bumpy_surface  # noqa: E402
from frisicp_ros.node.node import RegistrationNode  # noqa: E402

pytestmark = pytest.mark.ros

TIMEOUT = 20.0
RELIABLE = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)


class Probe:
    """The test's node: publishes model/data, records everything the frisicp node publishes."""

    def __init__(self, context: rclpy.Context) -> None:
        self.node = rclpy.create_node("probe", context=context)
        self.model_pub = self.node.create_publisher(PointCloud2, "model", RELIABLE)
        self.data_pub = self.node.create_publisher(PointCloud2, "data", RELIABLE)
        self.received: dict[str, list] = {
            name: [] for name in ("transform", "pose", "scale", "rms", "similarity", "aligned", "diagnostics")
        }
        for name, msg_type in (
            ("transform", TransformStamped),
            ("pose", PoseWithCovarianceStamped),
            ("scale", Vector3Stamped),
            ("rms", Vector3Stamped),
            ("similarity", Float64MultiArray),
            ("aligned", PointCloud2),
        ):
            self.node.create_subscription(msg_type, f"/frisicp/{name}", self.received[name].append, RELIABLE)
        self.node.create_subscription(
            DiagnosticArray, "/diagnostics", self.received["diagnostics"].append, 10
        )
        self.reset_client = self.node.create_client(Trigger, "/frisicp/reset")

    def clear(self) -> None:
        for values in self.received.values():
            values.clear()


@pytest.fixture(scope="module")
def ros():
    context = rclpy.Context()
    rclpy.init(context=context, domain_id=DOMAIN)
    node = RegistrationNode(
        context=context,
        parameter_overrides=[Parameter("max_points", value=3000), Parameter("diagnostics_period", value=0.3)],
    )
    probe = Probe(context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    executor.add_node(probe.node)
    spinner = threading.Thread(target=executor.spin, daemon=True)
    spinner.start()
    yield node, probe
    executor.shutdown(timeout_sec=5)
    node.destroy_node()
    probe.node.destroy_node()
    rclpy.shutdown(context=context)
    spinner.join(5)
    assert not spinner.is_alive() and not node._worker.is_alive()


def register_pair(probe: Probe, model, data) -> TransformStamped:
    """Publish the pair until the node answers for this data stamp; return that transform."""
    wanted = (data.header.stamp.sec, data.header.stamp.nanosec)

    def answered() -> bool:
        return any(
            (t.header.stamp.sec, t.header.stamp.nanosec) == wanted for t in probe.received["transform"]
        )

    def publish() -> None:
        probe.model_pub.publish(model)
        time.sleep(0.05)
        probe.data_pub.publish(data)

    assert wait_until(answered, TIMEOUT, action=publish, every=1.0), "no transform for the data stamp"
    return next(
        t for t in probe.received["transform"] if (t.header.stamp.sec, t.header.stamp.nanosec) == wanted
    )


def test_registers_pair_and_publishes_every_output(ros):
    _node, probe = ros
    probe.clear()
    model, data = scene_messages()
    transform = register_pair(probe, model, data)
    assert (transform.header.frame_id, transform.child_frame_id) == ("map", "velodyne")
    assert wait_until(
        lambda: probe.received["scale"] and probe.received["similarity"] and probe.received["rms"], 5.0
    )
    scale = probe.received["scale"][-1].vector.x
    estimate = transform_similarity(transform, scale)
    assert scale == pytest.approx(TRUTH.scale, rel=1e-3)
    np.testing.assert_allclose(estimate.rotation, TRUTH.rotation, atol=3e-3)
    np.testing.assert_allclose(estimate.translation, TRUTH.translation, atol=1e-2)
    matrix = probe.received["similarity"][-1]
    assert [(d.label, d.size, d.stride) for d in matrix.layout.dim] == [("rows", 4, 16), ("cols", 4, 4)]
    np.testing.assert_allclose(np.reshape(matrix.data, (4, 4)), estimate.matrix(), atol=1e-9)
    assert probe.received["rms"][-1].vector.x < 0.01


def test_pose_scale_and_rms_carry_the_data_stamp_and_the_cores_uncertainty(ros):
    node, probe = ros
    probe.clear()
    model, data = scene_messages(stamp_ns=1_700_000_000_750_000_000)
    transform = register_pair(probe, model, data)
    assert wait_until(
        lambda: probe.received["pose"] and probe.received["scale"] and probe.received["rms"], 5.0
    )
    pose, scale, rms = (probe.received[name][-1] for name in ("pose", "scale", "rms"))
    for message in (pose, scale, rms):
        assert message.header.stamp == data.header.stamp and message.header.frame_id == "map"
    outcome = node._status._last_registered  # the registration these messages came from
    assert outcome.stamp == (data.header.stamp.sec, data.header.stamp.nanosec)
    result = outcome.result
    # The covariance is the core's, exactly, in ROS order x y z roll pitch yaw.
    expected = result.uncertainty.pose_covariance(result.similarity)
    np.testing.assert_array_equal(np.reshape(pose.pose.covariance, (6, 6)), expected)
    assert np.all(np.diag(expected) > 0)
    p, q = pose.pose.pose.position, pose.pose.pose.orientation
    t, r = transform.transform.translation, transform.transform.rotation
    assert (p.x, p.y, p.z, q.x, q.y, q.z, q.w) == (t.x, t.y, t.z, r.x, r.y, r.z, r.w)
    sigma = result.uncertainty.scale
    assert (scale.vector.x, scale.vector.y, scale.vector.z) == pytest.approx(
        (result.similarity.scale, result.similarity.scale * sigma, sigma), rel=1e-12
    )
    assert (rms.vector.x, rms.vector.y, rms.vector.z) == pytest.approx(
        (result.rms, result.forward_rms, result.backward_rms), rel=1e-12
    )


def test_aligned_cloud_keeps_intensity_and_lands_on_model(ros):
    _node, probe = ros
    probe.clear()
    model, data = scene_messages(stamp_ns=1_700_000_001_000_000_000)
    register_pair(probe, model, data)
    assert wait_until(lambda: probe.received["aligned"], 5.0)
    aligned = probe.received["aligned"][-1]
    assert aligned.header.frame_id == "map" and aligned.header.stamp == data.header.stamp
    table = np.frombuffer(aligned.data, np.float32).reshape(-1, 4)
    np.testing.assert_array_equal(table[:, 3], np.arange(2000, dtype=np.float32))
    np.testing.assert_allclose(table[:, :3], TRUTH.apply(bumpy_surface(2000, seed=11)), atol=2e-2)


def test_diagnostics_report_rates_latency_and_result(ros):
    _node, probe = ros
    probe.clear()
    register_pair(probe, *scene_messages(stamp_ns=1_700_000_002_000_000_000))

    def ok_report():
        for array in probe.received["diagnostics"]:
            for status in array.status:
                values = {kv.key: kv.value for kv in status.values}
                if status.level == b"\x00" and "latency p50 (ms)" in values:
                    return values
        return None

    assert wait_until(lambda: ok_report() is not None, 5.0)
    values = ok_report()
    assert float(values["last rms"]) < 0.01 and values["last converged"] == "True"
    assert int(values["registered pairs"]) >= 1 and float(values["latency p50 (ms)"]) > 0
    for key in (
        "model rate (Hz)",
        "data rate (Hz)",
        "dropped pairs",
        "rejected data clouds",
        "last iterations",
        "conversion / registration",
        "down-sampling / registration",
        "output / registration",
        "registration CPU mean (ms)",
        "callback delay p95 (ms)",  # the subscription gets the message info: DDS receipt time
        "data transport p50 (ms)",
    ):
        assert key in values


def test_parameters_validated_at_run_time(ros):
    node, _ = ros
    result = node.set_parameters([Parameter("overlap", value=1.5)])[0]
    assert not result.successful and "overlap" in result.reason
    assert node.get_parameter("overlap").value == 0.0  # 0: estimated from the data
    result = node.set_parameters([Parameter("method", value="ransac")])[0]
    assert not result.successful and "method must be one of" in result.reason
    result = node.set_parameters([Parameter("model_qos", value="reliable")])[0]
    assert not result.successful  # read-only: subscriptions are made at start-up
    assert node.set_parameters([Parameter("overlap", value=0.9)])[0].successful
    registrar = node._registrar
    assert wait_until(
        lambda: registrar.settings.registration.overlap == 0.9 or registrar.pending_settings is not None, 2.0
    )
    assert node.set_parameters([Parameter("overlap", value=0.0)])[0].successful


def test_reset_service_clears_model_and_warm_start(ros):
    node, probe = ros
    register_pair(probe, *scene_messages(stamp_ns=1_700_000_003_000_000_000))
    assert probe.reset_client.wait_for_service(timeout_sec=TIMEOUT)
    future = probe.reset_client.call_async(Trigger.Request())
    assert wait_until(future.done, TIMEOUT) and future.result().success
    assert node._pairer.latest_model is None
    assert wait_until(lambda: node._registrar.previous is None, 2.0)
    probe.clear()
    # Data alone does not register after the reset: the model is gone.
    _, data = scene_messages(stamp_ns=1_700_000_004_000_000_000)
    probe.data_pub.publish(data)
    time.sleep(1.0)
    assert not probe.received["transform"]


def test_bad_inputs_are_skipped_counted_and_the_node_keeps_registering(ros):
    node, probe = ros
    model, data = scene_messages(stamp_ns=1_700_000_005_000_000_000)
    register_pair(probe, model, data)
    types_ok = cloud_message(bumpy_surface(100), "velodyne", 1)
    bad_clouds = {
        "length": _replace(types_ok, data=types_ok.data[:-3]),
        "missing_field": _replace(types_ok, fields=types_ok.fields[:2]),
        "overlapping": _replace(types_ok, fields=[types_ok.fields[0], _field("y", 2), types_ok.fields[2]]),
        "point_step": _replace(types_ok, point_step=8),
        "datatype": _replace(types_ok, fields=[_field("x", 0, datatype=42), *types_ok.fields[1:]]),
        "empty": cloud_message(np.zeros((0, 3)), "velodyne", 1),
        "all_nan": cloud_message(np.full((50, 3), np.nan), "velodyne", 1),
        "degenerate": cloud_message(np.outer(np.linspace(0, 1, 100), [1.0, 2.0, 3.0]), "velodyne", 1),
    }
    rejected_before = node._status._rejected.copy()
    for index, bad in enumerate(bad_clouds.values()):
        bad.header.stamp.sec, bad.header.stamp.nanosec = 1_700_000_100 + index, 0
        probe.data_pub.publish(bad)
        time.sleep(0.3)  # one at a time: the newest-wins slot would otherwise drop some
    rejected = node._status._rejected
    assert wait_until(
        lambda: (
            (rejected["data"] - rejected_before["data"] + rejected["pair"] - rejected_before["pair"])
            == len(bad_clouds)
        ),
        10.0,
    ), rejected
    # a bad model, then frames changing mid-stream in synchronized mode
    probe.model_pub.publish(bad_clouds["all_nan"])
    probe.data_pub.publish(data)
    assert wait_until(lambda: rejected["model"] > rejected_before["model"], 10.0)
    assert node.set_parameters(
        [Parameter("pairing", value="synchronized"), Parameter("sync_tolerance", value=0.1)]
    )[0].successful
    good_model, good_data = scene_messages(stamp_ns=1_700_000_006_000_000_000)
    register_pair(probe, good_model, good_data)
    moved_model, moved_data = scene_messages(stamp_ns=1_700_000_007_000_000_000)
    moved_data.header.frame_id = "another_lidar"
    probe.model_pub.publish(moved_model)
    probe.data_pub.publish(moved_data)
    assert wait_until(lambda: "frame mismatch" in node._status._last_rejection, 10.0)
    # ... and it still registers a good pair afterwards
    probe.clear()
    transform = register_pair(probe, *scene_messages(stamp_ns=1_700_000_008_000_000_000))
    assert transform_similarity(transform, 1.5).translation == pytest.approx(TRUTH.translation, abs=1e-2)
    assert node.set_parameters([Parameter("pairing", value="latest_model")])[0].successful


def _field(name: str, offset: int, datatype: int = 7):
    from sensor_msgs.msg import PointField

    return PointField(name=name, offset=offset, datatype=datatype, count=1)


def _replace(msg: PointCloud2, **changes) -> PointCloud2:
    copy = PointCloud2(
        header=msg.header,
        height=msg.height,
        width=msg.width,
        fields=list(msg.fields),
        is_bigendian=msg.is_bigendian,
        point_step=msg.point_step,
        row_step=msg.row_step,
        data=msg.data,
        is_dense=msg.is_dense,
    )
    for key, value in changes.items():
        setattr(copy, key, value)
    return copy
