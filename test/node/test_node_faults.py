"""The node in-process under faults: failures while publishing, a dead worker, parameter changes
with a latched model, a garbage cloud between good ones.

Domain 135 (unique to this module), loopback discovery only.
"""

from __future__ import annotations

import numpy as np
import pytest
from support.data import with_absurd_scale
from support.ros import TRUTH, NodeAndProbe, ros_environment, scene_messages, transform_similarity, wait_until

DOMAIN = 135
ros_environment(DOMAIN)

from geometry_msgs.msg import TransformStamped  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy  # noqa: E402
from sensor_msgs.msg import PointCloud2  # noqa: E402

from frisicp_core import rotation_angle  # noqa: E402
from frisicp_ros.node.status import ERROR, OK  # noqa: E402

pytestmark = pytest.mark.ros

TIMEOUT = 20.0
RELIABLE = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
LATCHED = QoSProfile(
    depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL
)


class Running(NodeAndProbe):
    """A node and a probe in one executor on a thread."""

    def __init__(self, *parameters: Parameter) -> None:
        overrides = [Parameter("max_points", value=2000), Parameter("model_qos", value="transient_local")]
        super().__init__(DOMAIN, [*overrides, *parameters], "fault_probe")
        self.transforms: list[TransformStamped] = []
        self.probe.create_subscription(
            TransformStamped, "/frisicp/transform", self.transforms.append, RELIABLE
        )
        self.model_pub = self.probe.create_publisher(PointCloud2, "model", LATCHED)
        self.data_pub = self.probe.create_publisher(PointCloud2, "data", RELIABLE)
        self.start()

    def answered(self, data: PointCloud2) -> TransformStamped | None:
        wanted = (data.header.stamp.sec, data.header.stamp.nanosec)
        return next(
            (t for t in self.transforms if (t.header.stamp.sec, t.header.stamp.nanosec) == wanted), None
        )

    def register(self, data: PointCloud2) -> TransformStamped:
        assert wait_until(
            lambda: self.answered(data) is not None,
            TIMEOUT,
            action=lambda: self.data_pub.publish(data),
            every=1.0,
        ), "no transform for the data stamp"
        transform = self.answered(data)
        assert transform is not None
        return transform

    def report(self):
        node = self.node
        return node._status.report(node._slot.dropped, node._pairer.unpaired_data, True)


@pytest.fixture
def running():
    started = Running()
    yield started
    started.close()


def stamped(stamp_ns: int, n: int = 2000):
    return scene_messages(n, stamp_ns=stamp_ns)


def assert_truth(transform: TransformStamped) -> None:
    estimate = transform_similarity(transform, TRUTH.scale)
    assert np.degrees(rotation_angle(estimate.rotation.T @ TRUTH.rotation)) < 1.0
    np.testing.assert_allclose(estimate.translation, TRUTH.translation, atol=0.02)


def test_an_exception_while_publishing_is_counted_and_the_worker_goes_on(running):
    model, data = stamped(1_700_000_000_000_000_000)
    running.model_pub.publish(model)
    assert_truth(running.register(data))
    publisher = running.node._output_publishers["scale"]
    real_publish = publisher.publish
    failures = []

    def failing_once(message):
        if not failures:
            failures.append(message)
            raise AssertionError("The 'sec' field must be an integer in [-2147483648, 2147483647]")
        real_publish(message)

    publisher.publish = failing_once
    _, failing = stamped(1_700_000_001_000_000_000)
    running.data_pub.publish(failing)
    assert wait_until(lambda: running.report().values["publish errors"] == "1", TIMEOUT)
    assert "sec" in running.report().values["last publish error"]
    _, after = stamped(1_700_000_002_000_000_000)
    assert_truth(running.register(after))  # the worker is alive and registering
    assert running.node._worker.is_alive()
    assert running.report().level == OK


def test_a_dead_worker_shows_as_error_not_registering(running):
    model, data = stamped(1_700_000_010_000_000_000)
    running.model_pub.publish(model)
    assert_truth(running.register(data))

    def broken_take(timeout=None):
        raise RuntimeError("slot broken")

    running.node._slot.take = broken_take  # a bug outside any one pair: the loop itself fails
    assert wait_until(lambda: not running.node._worker.is_alive(), TIMEOUT)
    report = running.report()
    running.node._publish_diagnostics()  # the timer's check: the thread is gone
    report = running.report()
    assert report.level == ERROR and "worker stopped" in report.message and "slot broken" in report.message


@pytest.mark.parametrize(
    "changes",
    [
        [Parameter("sync_tolerance", value=0.2)],
        [Parameter("pairing", value="synchronized"), Parameter("sync_tolerance", value=10.0)],
    ],
    ids=["sync_tolerance", "pairing"],
)
def test_a_parameter_change_keeps_the_latched_model_and_the_counters(running, changes):
    """A latched map arrives once: a valid change of pairing or tolerance discarded it."""
    model, data = stamped(1_700_000_020_000_000_000)
    running.model_pub.publish(model)
    assert_truth(running.register(data))
    registered_before = running.report().values["registered pairs"]
    assert all(result.successful for result in running.node.set_parameters(changes))
    _, later = stamped(1_700_000_020_500_000_000)  # within 10 s of the model's stamp
    assert_truth(running.register(later))
    assert int(running.report().values["registered pairs"]) == int(registered_before) + 1


def test_a_garbage_cloud_is_never_ok_and_the_next_good_pair_is_right(running):
    model, data = stamped(1_700_000_030_000_000_000)
    running.model_pub.publish(model)
    assert_truth(running.register(data))
    _, garbage = stamped(1_700_000_031_000_000_000)
    garbage.is_bigendian = True  # little-endian bytes flagged big-endian: parses, is nonsense
    running.data_pub.publish(garbage)
    status = running.node._status
    assert wait_until(lambda: status._consecutive_failures == 1, TIMEOUT), running.report()
    report = running.report()
    assert report.level != OK, report
    assert running.answered(garbage) is None, "an implausible result was published"
    assert running.node._registrar.previous is None
    _, good = stamped(1_700_000_032_000_000_000)
    assert_truth(running.register(good))
    assert running.report().level == OK


def test_diagnostics_never_say_ok_for_an_absurd_scale(running):
    """Whatever the verdict's thresholds: a scale of 1.5e40 is not 'registering'."""
    model, data = stamped(1_700_000_040_000_000_000)
    running.model_pub.publish(model)
    assert_truth(running.register(data))
    outcome = running.node._status._last_registered
    assert outcome is not None
    absurd = with_absurd_scale(outcome)
    running.node.publish_outcome(absurd, data)
    report = running.report()
    assert report.level != OK and "1.5e+40" in report.message
