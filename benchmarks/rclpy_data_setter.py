"""How long rclpy's generated setter takes to store 1.6 MB in ``PointCloud2.data``, by value type.

    .venv/bin/python benchmarks/rclpy_data_setter.py
    ROS_PYTHON_CHECK_FIELDS=1 .venv/bin/python benchmarks/rclpy_data_setter.py

Why frisicp_ros.stream.outputs fills ``data`` with an ``array.array('B')`` (frombytes of the numpy
buffer): other value types go through per-element conversion or checks. Figures: docs/node.md.
No ROS communication (messages are only constructed).
"""

from __future__ import annotations

import array
import time
from collections.abc import Callable

import numpy as np
from sensor_msgs.msg import PointCloud2

SIZE = 100_000 * 16  # a 100k-point cloud of x y z intensity (float32)


def best_of(make_value: Callable[[], object], repeats: int = 3) -> float:
    best = float("inf")
    for _ in range(repeats):
        msg, value = PointCloud2(), make_value()
        start = time.perf_counter()
        msg.data = value
        best = min(best, time.perf_counter() - start)
    return best


def main() -> None:
    raw = np.random.default_rng(0).integers(0, 255, SIZE, dtype=np.uint8)

    def filled_array() -> array.array:
        out = array.array("B")
        out.frombytes(raw.data)
        return out

    cases = {
        "array.array('B') + frombytes": filled_array,
        "bytes": raw.tobytes,
        "memoryview": lambda: memoryview(raw),
        "numpy uint8 array": lambda: raw,
        "list of int": raw.tolist,
    }
    for label, make_value in cases.items():
        try:
            print(f"{label:32s} {best_of(make_value) * 1e3:9.2f} ms")
        except AssertionError:
            print(f"{label:32s}  rejected by the field check")


if __name__ == "__main__":
    main()
