"""A scene the blind cold search gets wrong and an initial guess gets right (shared by the
stream and node tests of initial guesses)."""

from __future__ import annotations

import math

import numpy as np

from frisicp_core import Similarity, axis_angle_rotation, bumpy_surface
from frisicp_ros.stream.outputs import MessageTypes, rclpy_message_types
from frisicp_ros.stream.pointcloud2 import points_to_parts

GUESS_SIGMAS = (5.0, 0.1)  # degrees, model units


def turned_crop_clouds(types: MessageTypes | None = None):
    """A 30 % strip of a surface turned 150 degrees and scaled 2x: the blind search settles 120
    degrees off (frisicp_core's test_initial_guess); ``rough`` is 8 degrees and 0.1 off the truth.

    Returns (model cloud, three data clouds stamped 0.1 s apart, truth, rough).
    """
    types = types or rclpy_message_types()
    model = bumpy_surface(20000, seed=3)
    crop = model[model[:, 0] < np.quantile(model[:, 0], 0.3)]
    rng = np.random.default_rng(7)
    crop = crop[rng.choice(len(crop), 3000, replace=False)] + rng.normal(scale=0.003, size=(3000, 3))
    truth = Similarity(2.0, axis_angle_rotation([0.2, 0.3, 1.0], np.deg2rad(150.0)), [0.3, -0.2, 1.0])
    rough = Similarity(1.0, axis_angle_rotation([0.2, 0.3, 1.0], np.deg2rad(158.0)), [0.4, -0.2, 1.0])

    def cloud(points, frame, stamp_ns):
        return types.point_cloud(points_to_parts(points), types.header(stamp_ns, frame))

    data = truth.inverse().apply(crop)
    start = 1_700_000_300_000_000_000
    clouds = [cloud(data, "lidar", start + k * 100_000_000) for k in (1, 2, 3)]
    return cloud(model, "map", start), clouds, truth, rough


def guess_covariance() -> np.ndarray:
    rotation_deg, translation = GUESS_SIGMAS
    return np.diag([translation**2] * 3 + [math.radians(rotation_deg) ** 2] * 3).reshape(-1)


def guess_message(rough: Similarity, frame: str):
    """``rough`` as the PoseWithCovarianceStamped RViz would send (rclpy)."""
    from geometry_msgs.msg import PoseWithCovarianceStamped

    msg = PoseWithCovarianceStamped()
    msg.header.frame_id = frame
    p, q = msg.pose.pose.position, msg.pose.pose.orientation
    p.x, p.y, p.z = (float(v) for v in rough.translation)
    q.x, q.y, q.z, q.w = (float(v) for v in rough.quaternion())
    msg.pose.covariance = guess_covariance()
    return msg
