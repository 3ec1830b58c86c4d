"""The shapes of the ROS messages the stream reads, as ``typing.Protocol`` classes.

Attributes only: mypy checks the stream against them, while at run time messages stay
duck-typed. rclpy messages (the node), rosbags' message dataclasses, ``frisicp_ros.bag.pairs``'
PlainCloud (the bag mode) and the tests' plain objects all fit. Members are read-only properties,
so frozen dataclasses fit too (a protocol's plain attribute would demand a settable one). No ROS
import here: the stream layer must run without ROS.
"""

from __future__ import annotations

import array
from collections.abc import Sequence
from typing import Protocol, TypeAlias

import numpy as np

# PointCloud2.data: rclpy fills it with array.array('B'), rosbags and PlainCloud with a uint8 array.
CloudBytes: TypeAlias = "bytes | bytearray | memoryview | array.array[int] | np.ndarray"


class TimeLike(Protocol):
    """builtin_interfaces/Time."""

    @property
    def sec(self) -> int: ...

    @property
    def nanosec(self) -> int: ...


class HeaderLike(Protocol):
    """std_msgs/Header."""

    @property
    def stamp(self) -> TimeLike: ...

    @property
    def frame_id(self) -> str: ...


class StampedLike(Protocol):
    """Any message with a std_msgs/Header."""

    @property
    def header(self) -> HeaderLike: ...


class PointFieldLike(Protocol):
    """sensor_msgs/PointField."""

    @property
    def name(self) -> str: ...

    @property
    def offset(self) -> int: ...

    @property
    def datatype(self) -> int: ...

    @property
    def count(self) -> int: ...


class CloudLayoutLike(Protocol):
    """The part of a sensor_msgs/PointCloud2 that places the points in ``data``."""

    @property
    def height(self) -> int: ...

    @property
    def width(self) -> int: ...

    @property
    def fields(self) -> Sequence[PointFieldLike]: ...

    @property
    def is_bigendian(self) -> bool: ...

    @property
    def point_step(self) -> int: ...

    @property
    def row_step(self) -> int: ...

    @property
    def data(self) -> CloudBytes: ...


class PointCloud2Like(CloudLayoutLike, StampedLike, Protocol):
    """sensor_msgs/PointCloud2."""

    @property
    def is_dense(self) -> bool: ...


class XYZLike(Protocol):
    """geometry_msgs/Point (or Vector3)."""

    @property
    def x(self) -> float: ...

    @property
    def y(self) -> float: ...

    @property
    def z(self) -> float: ...


class QuaternionLike(XYZLike, Protocol):
    """geometry_msgs/Quaternion."""

    @property
    def w(self) -> float: ...


class PoseLike(Protocol):
    """geometry_msgs/Pose."""

    @property
    def position(self) -> XYZLike: ...

    @property
    def orientation(self) -> QuaternionLike: ...


class PoseWithCovarianceLike(Protocol):
    """geometry_msgs/PoseWithCovariance: ``covariance`` holds 36 values, row-major."""

    @property
    def pose(self) -> PoseLike: ...

    @property
    def covariance(self) -> Sequence[float] | np.ndarray: ...


class PoseWithCovarianceStampedLike(StampedLike, Protocol):
    """geometry_msgs/PoseWithCovarianceStamped."""

    @property
    def pose(self) -> PoseWithCovarianceLike: ...
