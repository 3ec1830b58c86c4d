"""Helpers for the tests that run real rclpy + DDS: isolated domains, clouds, bounded waits."""

from __future__ import annotations

import os
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any

import numpy as np

from frisicp_core import Similarity, axis_angle_rotation, bumpy_surface
from frisicp_ros.node.message_types import rclpy_message_types
from frisicp_ros.stream.pointcloud2 import points_to_parts

# Rotation by 20 degrees about a tilted axis; each node test checks the node recovers this.
TRUTH = Similarity(1.5, axis_angle_rotation([0.3, 1.0, 0.2], np.deg2rad(20.0)), np.array([0.5, -1.0, 2.0]))


def ros_environment(domain_id: int) -> dict[str, str]:
    """The environment for a test module's ROS processes: loopback-only DDS in its own domain.

    Discovery is limited to loopback in this process too. The domain is *not* set in this
    process's environment (modules are imported together, and the last import would win): pass
    ``domain_id`` to ``rclpy.init`` (``spinning_node`` does).
    """
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    os.environ.pop("ROS_STATIC_PEERS", None)
    os.environ.pop("ROS_DOMAIN_ID", None)
    return {**os.environ, "ROS_DOMAIN_ID": str(domain_id)}


def cloud_message(points: np.ndarray, frame: str, stamp_ns: int, **extra: np.ndarray):
    types = rclpy_message_types()
    return types.point_cloud(points_to_parts(points, extra or None), types.header(stamp_ns, frame))


def scene_messages(n: int = 2000, stamp_ns: int = 1_700_000_000_250_000_000):
    """(model, data) rclpy clouds with model = TRUTH(data); data carries an intensity field."""
    data = bumpy_surface(n, seed=11)
    model = cloud_message(TRUTH.apply(data), "map", stamp_ns - 50_000_000)
    return model, cloud_message(data, "velodyne", stamp_ns, intensity=np.arange(n, dtype=np.float32))


def wait_until(
    condition: Callable[[], bool],
    timeout: float,
    poll: float = 0.02,
    action: Callable[[], None] | None = None,
    every: float = 0.5,
) -> bool:
    """Poll ``condition`` up to ``timeout`` s, running ``action`` every ``every`` s (re-publishing)."""
    deadline = time.monotonic() + timeout
    next_action = 0.0
    while time.monotonic() < deadline:
        if action is not None and time.monotonic() >= next_action:
            action()
            next_action = time.monotonic() + every
        if condition():
            return True
        time.sleep(poll)
    return condition()


def transform_similarity(transform_msg, scale: float) -> Similarity:
    t, q = transform_msg.transform.translation, transform_msg.transform.rotation
    return Similarity.from_quaternion(scale, [q.x, q.y, q.z, q.w], [t.x, t.y, t.z])


@contextmanager
def spinning_node(name: str, domain_id: int) -> Iterator[Any]:
    """A node of its own context in ``domain_id``, spun by an executor on a thread."""
    import rclpy
    from rclpy.executors import SingleThreadedExecutor

    context = rclpy.Context()
    rclpy.init(context=context, domain_id=domain_id)
    node = rclpy.create_node(name, context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    spinner = threading.Thread(target=executor.spin, daemon=True)
    spinner.start()
    try:
        yield node
    finally:
        executor.shutdown(timeout_sec=5)
        node.destroy_node()
        rclpy.shutdown(context=context)
        spinner.join(5)


class NodeAndProbe:
    """``RegistrationNode`` in this process plus a probe node, one executor spinning both on a
    thread, in their own context in ``domain_id``. ``close()`` takes it all down."""

    def __init__(self, domain_id: int, parameters: list[Any], probe_name: str) -> None:
        import rclpy
        from rclpy.executors import SingleThreadedExecutor

        from frisicp_ros.node.node import RegistrationNode

        self.context = rclpy.Context()
        rclpy.init(context=self.context, domain_id=domain_id)
        self.node = RegistrationNode(context=self.context, parameter_overrides=parameters)
        self.probe = rclpy.create_node(probe_name, context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.executor.add_node(self.probe)
        self.spinner = threading.Thread(target=self.executor.spin, daemon=True)

    def start(self) -> None:
        """Spin (after the probe's publishers and subscriptions are made)."""
        self.spinner.start()

    def close(self) -> None:
        import rclpy

        self.executor.shutdown(timeout_sec=5)
        self.node.destroy_node()
        self.probe.destroy_node()
        rclpy.shutdown(context=self.context)
        self.spinner.join(5)
