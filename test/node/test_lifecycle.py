"""register_lifecycle_node driven through its lifecycle services, as a lifecycle manager (or
`ros2 lifecycle set`, not installable here) drives it: outputs only while active.

Domain 138 (unique to this module), loopback discovery only.
"""

from __future__ import annotations

import threading
import time

import pytest
from support.ros import TRUTH, ros_environment, scene_messages, transform_similarity, wait_until

DOMAIN = 138
ros_environment(DOMAIN)

import rclpy  # noqa: E402
from diagnostic_msgs.msg import DiagnosticArray  # noqa: E402
from geometry_msgs.msg import PoseWithCovarianceStamped, TransformStamped  # noqa: E402
from lifecycle_msgs.msg import Transition  # noqa: E402
from lifecycle_msgs.srv import ChangeState, GetState  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from rclpy.qos import QoSProfile, ReliabilityPolicy  # noqa: E402
from sensor_msgs.msg import PointCloud2  # noqa: E402

from frisicp_ros.node.lifecycle import RegistrationLifecycleNode  # noqa: E402

pytestmark = pytest.mark.ros

RELIABLE = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
QUIET_SECONDS = 1.5  # how long "no output" is watched for (several diagnostics periods)


class Manager:
    """The test's node: a lifecycle manager's service clients plus a publisher and recorder."""

    def __init__(self, context: rclpy.Context) -> None:
        self.node = rclpy.create_node("lifecycle_manager", context=context)
        self.change = self.node.create_client(ChangeState, "/frisicp/change_state")
        self.get = self.node.create_client(GetState, "/frisicp/get_state")
        self.model_pub = self.node.create_publisher(PointCloud2, "model", RELIABLE)
        self.data_pub = self.node.create_publisher(PointCloud2, "data", RELIABLE)
        self.transforms: list[TransformStamped] = []
        self.poses: list[PoseWithCovarianceStamped] = []
        self.diagnostics: list[DiagnosticArray] = []
        self.node.create_subscription(
            TransformStamped, "/frisicp/transform", self.transforms.append, RELIABLE
        )
        self.node.create_subscription(PoseWithCovarianceStamped, "/frisicp/pose", self.poses.append, RELIABLE)
        self.node.create_subscription(DiagnosticArray, "/diagnostics", self.diagnostics.append, 10)

    def call(self, client, request):
        assert client.wait_for_service(timeout_sec=10.0), f"{client.srv_name} not offered"
        future = client.call_async(request)
        assert wait_until(future.done, 10.0), f"{client.srv_name} did not answer"
        return future.result()

    def state(self) -> str:
        return self.call(self.get, GetState.Request()).current_state.label

    def transition(self, transition_id: int) -> bool:
        return self.call(self.change, ChangeState.Request(transition=Transition(id=transition_id))).success

    def clear(self) -> None:
        for received in (self.transforms, self.poses, self.diagnostics):
            received.clear()

    def publish_pair(self, model, data) -> None:
        if model is not None:
            self.model_pub.publish(model)
            time.sleep(0.05)
        self.data_pub.publish(data)

    def assert_quiet(self, model, data) -> None:
        """Clouds keep coming, nothing comes out: no pose, no transform, no diagnostics."""
        deadline = time.monotonic() + QUIET_SECONDS
        while time.monotonic() < deadline:
            self.publish_pair(model, data)
            time.sleep(0.25)
        assert (self.transforms, self.poses, self.diagnostics) == ([], [], [])


@pytest.fixture
def managed(request):
    context = rclpy.Context()
    rclpy.init(context=context, domain_id=DOMAIN)
    overrides = [Parameter("max_points", value=2000), Parameter("diagnostics_period", value=0.2)]
    node = RegistrationLifecycleNode(
        context=context, parameter_overrides=overrides + getattr(request, "param", [])
    )
    manager = Manager(context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    executor.add_node(manager.node)
    spinner = threading.Thread(target=executor.spin, daemon=True)
    spinner.start()
    yield node, manager
    executor.shutdown(timeout_sec=5)
    node.destroy_node()
    manager.node.destroy_node()
    rclpy.shutdown(context=context)
    spinner.join(5)


def test_outputs_come_only_while_active_through_every_transition(managed):
    node, manager = managed
    model, data = scene_messages(2000, stamp_ns=1_700_000_100_000_000_000)
    assert manager.state() == "unconfigured"
    manager.assert_quiet(model, data)

    assert manager.transition(Transition.TRANSITION_CONFIGURE)
    assert manager.state() == "inactive"
    manager.assert_quiet(model, data)

    assert manager.transition(Transition.TRANSITION_ACTIVATE)
    assert manager.state() == "active"
    assert wait_until(lambda: manager.transforms, 20.0, action=lambda: manager.publish_pair(model, data))
    assert wait_until(lambda: manager.poses and manager.diagnostics, 5.0)
    estimate = transform_similarity(manager.transforms[-1], TRUTH.scale)
    assert abs(estimate.rotation - TRUTH.rotation).max() < 3e-3

    assert manager.transition(Transition.TRANSITION_DEACTIVATE)
    assert manager.state() == "inactive"
    time.sleep(0.3)  # outputs already in flight at the transition
    manager.clear()
    manager.assert_quiet(model, data)

    # Active again: the model received before is kept, so data alone is registered.
    assert manager.transition(Transition.TRANSITION_ACTIVATE)
    later = scene_messages(2000, stamp_ns=1_700_000_200_000_000_000)[1]
    assert wait_until(lambda: manager.transforms, 20.0, action=lambda: manager.publish_pair(None, later))
    assert manager.transforms[-1].header.stamp == later.header.stamp

    assert manager.transition(Transition.TRANSITION_DEACTIVATE)
    assert manager.transition(Transition.TRANSITION_CLEANUP)
    assert manager.state() == "unconfigured"
    assert not node._worker.is_alive()
    assert manager.transition(Transition.TRANSITION_UNCONFIGURED_SHUTDOWN)
    assert manager.state() == "finalized"


@pytest.mark.parametrize("managed", [[Parameter("method", value="ransac")]], indirect=True)
def test_a_bad_parameter_fails_configure_and_a_corrected_one_configures(managed, capfd):
    node, manager = managed
    assert not manager.transition(Transition.TRANSITION_CONFIGURE)
    assert manager.state() == "unconfigured"
    assert "configure failed: ValueError: method must be one of" in capfd.readouterr().err
    assert node.set_parameters([Parameter("method", value="icp")])[0].successful
    assert manager.transition(Transition.TRANSITION_CONFIGURE)
    assert manager.state() == "inactive"
    assert node._registrar.settings.registration.method.value == "icp"
