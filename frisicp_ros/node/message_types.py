"""The rclpy flavour of ``frisicp_ros.stream.outputs.MessageTypes``: the message classes of the
outputs from the installed ROS message packages (the stream layer imports no ROS package).
"""

from __future__ import annotations

import array
from collections.abc import Callable
from importlib import import_module
from typing import Any

import numpy as np

from frisicp_ros.stream.outputs import OUTPUT_MESSAGE_TYPES, TF_TYPE, MessageTypes


def _rclpy_array(typecode: str, dtype: type[np.generic]) -> Callable[[np.ndarray], array.array[Any]]:
    """array.array is stored as is by rclpy's generated setters; frombytes is one memcpy.

    (Bytes, lists and memoryviews go through per-element checks instead: see docs/node.md.)
    """

    def convert(values: np.ndarray) -> array.array[Any]:
        out = array.array(typecode)
        out.frombytes(np.ascontiguousarray(values, dtype=dtype).data.cast("B"))
        return out

    return convert


def rclpy_message_types() -> MessageTypes:
    """The rclpy classes of the outputs, looked up by type name.

    tf2_msgs is not on PyPI: when it is not importable, TFMessage is missing from the result
    (``TF_TYPE in types`` says whether it is there).
    """
    classes = {}
    for name in (*OUTPUT_MESSAGE_TYPES, TF_TYPE):
        package, _, message = name.split("/")
        try:
            classes[name] = getattr(import_module(f"{package}.msg"), message)
        except ImportError:
            if name != TF_TYPE:
                raise
    return MessageTypes(classes, _rclpy_array("B", np.uint8), _rclpy_array("d", np.float64))
