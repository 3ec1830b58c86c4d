"""Where the bag mode's results go: a line-flushed JSONL file and a rosbag2 (mcap) result bag.

Both are written as results come in, so an interrupted run keeps everything computed so far.
The result bag is written under a temporary name beside the target and renamed on close, so the
target name only ever holds a complete, readable bag.
"""

from __future__ import annotations

import json
import math
import os
import shutil
import sys
from collections.abc import Mapping
from pathlib import Path
from typing import Any, TextIO

from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_typestore

from frisicp_ros.bag.pairs import BagPair
from frisicp_ros.stream.outputs import (
    OUTPUT_TOPICS,
    TF_TYPE,
    MessageTypes,
    result_summary,
    rosbags_message_types,
)
from frisicp_ros.stream.pipeline import PairOutcome, Registered, Rejected


class OutputError(Exception):
    """An output cannot be created (exists, no permission, disk full)."""


def pair_record(pair: BagPair, outcome: PairOutcome) -> dict[str, object]:
    """One JSON line: which clouds, then the registration.

    ``ok`` is true only for a pose to use: registered and ``reliable``. Otherwise ``reason`` says
    why: a rejected pair (also in ``rejection``, with ``rejected_input``) or an implausible result
    (its numbers are still given, for diagnosis). ``data_depth_steps``, only where found: the
    data clouds' coarse depth steps (``frisicp_ros.stream.depth_check``); ``depth_averaged``
    (from :func:`result_summary`), only where done: the voxel edges [data, model] both clouds were
    averaged over (``frisicp_core.terraces``).
    """
    record: dict[str, object] = {
        "pair": pair.index,
        "stamp_ns": pair.data.bag_ns,  # bag (receive) time of the data cloud
        "header_stamp_ns": outcome.stamp_ns,
        "model_stamp_ns": pair.model.bag_ns,
        "model_frame": outcome.model_frame,
        "data_frame": outcome.data_frame,
        "ok": isinstance(outcome, Registered) and outcome.reliable,
    }
    if isinstance(outcome, Rejected):
        record.update(reliable=False, reason=outcome.reason, rejection=outcome.reason)
        record["rejected_input"] = outcome.input
        return record
    record.update(result_summary(outcome.result))
    record["iterations_per_level"] = list(outcome.result.iterations)
    steps = outcome.depth_steps
    if steps is not None and steps.coarse:
        record["data_depth_steps"] = {
            "depth": steps.depth,
            "step": steps.step,
            "median_depth": steps.median_depth,
            "share": steps.share,
        }
    return record


def json_ready(value: object) -> object:
    """``value`` with every non-finite float as None: NaN and Infinity are not JSON."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {key: json_ready(item) for key, item in value.items()}
    if isinstance(value, list | tuple):
        return [json_ready(item) for item in value]
    return value


class JsonLines:
    """One JSON object per line, flushed per line; ``-`` is stdout."""

    def __init__(self, target: str) -> None:
        self.target = target
        if target == "-":
            self.stream: TextIO = sys.stdout
        else:
            try:
                self.stream = open(target, "w", encoding="utf-8", buffering=1)  # noqa: SIM115
            except OSError as err:
                raise OutputError(f"cannot write {target}: {err.strerror or err}") from None
        self.lines = 0

    def write(self, record: Mapping[str, object]) -> None:
        try:
            self.stream.write(json.dumps(json_ready(record), allow_nan=False) + "\n")
            self.stream.flush()
        except BrokenPipeError:
            # `frisicp bag ... | head`: the reader left. Point stdout at /dev/null so Python's own
            # flush at exit does not fail again, and let the caller stop like an interrupt.
            os.dup2(os.open(os.devnull, os.O_WRONLY), self.stream.fileno())
            raise OutputError("the reader of the results closed the pipe") from None
        except OSError as err:
            raise OutputError(f"cannot write {self.target}: {err.strerror or err}") from None
        self.lines += 1

    def close(self) -> None:
        if self.stream is not sys.stdout:
            self.stream.close()


TF_TOPIC = "/tf"


class ResultBag:
    """A rosbag2 (mcap storage) with the node's output topics under ``prefix``, and ``/tf``.

    Message log times are the data clouds' bag times; headers carry their header stamps, as the
    live node's outputs would. ``/tf`` (tf2_msgs/TFMessage: the model frame to the data frame
    scaled by s) gives viewers such as Foxglove the frames to place ``aligned`` and ``pose`` in.
    """

    def __init__(self, path: str | Path, prefix: str, topics: tuple[str, ...]) -> None:
        self.path = Path(path)
        if self.path.exists():
            raise OutputError(f"{self.path} exists already; choose a new --out-bag folder")
        if not self.path.parent.is_dir():
            raise OutputError(f"{self.path.parent} is not a directory")
        # The bag is built as <target>.partial-<pid>/<name>: rosbags names the storage file after
        # the bag folder, so the finished bag's file is <name>.mcap, as if written in place.
        self.staging = self.path.with_name(f"{self.path.name}.partial-{os.getpid()}")
        self.temporary = self.staging / self.path.name
        self.typestore = get_typestore(Stores.ROS2_JAZZY)
        self.types: MessageTypes = rosbags_message_types(self.typestore)
        self.topics = topics
        self.names = {suffix: f"{prefix.rstrip('/')}/{suffix}" for suffix in topics}
        # Version 8 is what Jazzy's rosbag2 writes and every reader from Iron on understands.
        self.writer = Writer(self.temporary, version=8, storage_plugin=StoragePlugin.MCAP)
        try:
            self.staging.mkdir()
            self.writer.open()
            self.connections = {
                suffix: self.writer.add_connection(
                    self.names[suffix], OUTPUT_TOPICS[suffix], typestore=self.typestore
                )
                for suffix in topics
            }
            self.tf_connection = self.writer.add_connection(TF_TOPIC, TF_TYPE, typestore=self.typestore)
        except Exception as err:  # noqa: BLE001 - permission, disk full: all "cannot create"
            shutil.rmtree(self.staging, ignore_errors=True)
            raise OutputError(f"cannot create {self.temporary}: {err}") from None
        self.pairs = 0

    def write(self, bag_ns: int, messages: Mapping[str, Any], tf: Any = None) -> None:
        """One pair's output ``messages`` by topic suffix, and its TFMessage ``tf`` if given."""
        try:
            for suffix, message in messages.items():
                raw = self.typestore.serialize_cdr(message, OUTPUT_TOPICS[suffix])
                self.writer.write(self.connections[suffix], bag_ns, raw)
            if tf is not None:
                self.writer.write(self.tf_connection, bag_ns, self.typestore.serialize_cdr(tf, TF_TYPE))
        except OSError as err:  # a full disk: the pairs written so far stay readable after close
            raise OutputError(f"cannot write {self.temporary}: {err.strerror or err}") from None
        self.pairs += 1

    def close(self) -> Path:
        """Finish the bag and give it its name; returns that name."""
        self.writer.close()
        if self.path.exists():  # appeared while we were working: keep both, say so
            raise OutputError(f"{self.path} appeared meanwhile; the result bag is at {self.temporary}")
        os.replace(self.temporary, self.path)
        self.staging.rmdir()
        return self.path
