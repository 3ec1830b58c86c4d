"""How long rclpy's generated setter takes to store 1.6 MB in ``PointCloud2.data``, by value type.

    .venv/bin/python benchmarks/rclpy_data_setter.py
    ROS_PYTHON_CHECK_FIELDS=1 .venv/bin/python benchmarks/rclpy_data_setter.py
    .venv/bin/python benchmarks/rclpy_data_setter.py --quick   # each value type once

Why frisicp_ros.stream.outputs fills ``data`` with an ``array.array('B')`` (frombytes of the numpy
buffer): other value types go through per-element conversion or checks. Figures: docs/node.md.
No ROS communication (messages are only constructed). Exits 0 without measuring when the ROS
message packages are not installed, saying so.
"""

from __future__ import annotations

import array
import importlib.util
import sys
import time
from collections.abc import Callable

import numpy as np

from frisicp_bench import script

SIZE = 100_000 * 16  # a 100k-point cloud of x y z intensity (float32)


def best_of(make_value: Callable[[], object], repeats: int) -> float:
    from sensor_msgs.msg import PointCloud2

    best = float("inf")
    for _ in range(repeats):
        msg, value = PointCloud2(), make_value()
        start = time.perf_counter()
        msg.data = value
        best = min(best, time.perf_counter() - start)
    return best


def main(argv: list[str] | None = None) -> int:
    parser = script.parser(__file__, __doc__, "each value type once", repeats=3)
    args = script.parse(parser, argv)
    if importlib.util.find_spec("sensor_msgs") is None:
        return script.skip(args, "the ROS message packages are not installed: pip install -e '.[ros]'")
    repeats = 1 if args.quick else args.repeats
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
            print(f"{label:32s} {best_of(make_value, repeats) * 1e3:9.2f} ms")
        except AssertionError:
            print(f"{label:32s}  rejected by the field check")
    return 0


if __name__ == "__main__":
    sys.exit(main())
