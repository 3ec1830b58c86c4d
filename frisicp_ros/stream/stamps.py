"""Header stamps as integer nanoseconds: the one unit the stream pairs, predicts and reports in.

A ROS stamp is ``builtin_interfaces/Time`` (``sec``, ``nanosec``); these are its only conversions.
"""

from __future__ import annotations

from frisicp_ros.stream.messages import StampedLike

NS_PER_SECOND = 1_000_000_000


def time_ns(sec: int, nanosec: int) -> int:
    """``sec`` seconds and ``nanosec`` nanoseconds as integer nanoseconds (nanosec is not
    required to be below 1e9: a stamp that is not normalised keeps its value)."""
    return int(sec) * NS_PER_SECOND + int(nanosec)


def stamp_ns(msg: StampedLike) -> int:
    """The header stamp of a message (anything with ``header.stamp.sec/nanosec``) in nanoseconds."""
    stamp = msg.header.stamp
    return time_ns(stamp.sec, stamp.nanosec)


def split_ns(ns: int) -> tuple[int, int]:
    """Integer nanoseconds as a normalised (sec, nanosec) pair, 0 <= nanosec < 1e9."""
    sec, nanosec = divmod(int(ns), NS_PER_SECOND)
    return sec, nanosec
