"""Reading bags without ROS: rosbag2 folders, bare ``.db3``/``.mcap`` files and ROS 1 ``.bag``.

MCAP storage goes through the ``mcap`` package's reader, which checks every chunk's CRC
(``frisicp_ros.bag.mcap_bag``), everything else through rosbags' ``AnyReader``, and a file cut
off part-way through ``frisicp_ros.bag.salvage`` (imported only then). This module turns the many
ways a bag can be unreadable into one ``BagError`` with a sentence a user can act on, and
iterates the messages of chosen topics in bag order with a deserialization failure reported per
message instead of ending the whole read.
"""

from __future__ import annotations

import contextlib
import functools
import re
from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_typestore

from frisicp_ros.bag.mcap_bag import McapBag

POINTCLOUD2 = "sensor_msgs/msg/PointCloud2"
# ROS 1 bags name the same type without "/msg/"; AnyReader keeps the bag's spelling.
POINTCLOUD2_NAMES = frozenset({POINTCLOUD2, "sensor_msgs/PointCloud2"})

BAG_SUFFIXES = (".db3", ".mcap", ".bag")


class BagError(Exception):
    """The bag cannot be opened or read any further; the message says why (and where)."""


@dataclass(frozen=True)
class TopicSummary:
    name: str
    msgtype: str
    count: int

    @property
    def is_pointcloud2(self) -> bool:
        return self.msgtype in POINTCLOUD2_NAMES


@dataclass(frozen=True)
class BagMessage:
    """One message of a chosen topic; ``message`` is None when it could not be deserialized."""

    index: int  # position among the yielded messages, 0-based
    topic: str
    stamp_ns: int  # the bag's receive time stamp
    message: object | None
    error: str | None = None


def bag_paths(path: Path) -> list[Path]:
    """What AnyReader must be given for ``path``: the path itself, after checks rosbags skips."""
    if not path.exists():
        raise BagError(f"{path}: no such file or directory")
    if path.is_dir():
        if not (path / "metadata.yaml").exists():
            storage = sorted(p.name for p in path.iterdir() if p.suffix in (".db3", ".mcap"))
            hint = f"; open one of its storage files instead: {', '.join(storage)}" if storage else ""
            raise BagError(f"{path}: a rosbag2 folder needs a metadata.yaml, and this one has none{hint}")
        return [path]
    if not path.is_file():  # opening a FIFO would wait for a writer forever
        raise BagError(f"{path}: not a regular file (a FIFO, socket or device); give a bag file or folder")
    if path.suffix not in BAG_SUFFIXES:
        raise BagError(f"{path}: not a bag (expected a rosbag2 folder or a {', '.join(BAG_SUFFIXES)} file)")
    try:
        with path.open("rb") as stream:
            stream.read(1)
    except OSError as err:
        raise BagError(f"{path}: cannot read it: {err.strerror or err}") from None
    return [path]


class Bag(Protocol):
    """What frisicp reads from a bag: rosbags' AnyReader, or a SalvagedBag of a damaged one."""

    @property
    def topics(self) -> Mapping[str, Any]: ...  # name -> info with msgtype, msgcount

    @property
    def connections(self) -> Sequence[Any]: ...  # each with topic, msgtype

    @property
    def start_time(self) -> int: ...

    @property
    def end_time(self) -> int: ...

    @property
    def message_count(self) -> int: ...

    def messages(self, connections: Any = ...) -> Iterator[tuple[Any, int, bytes]]: ...

    def deserialize(self, rawdata: bytes, typ: str) -> object: ...

    def close(self) -> None: ...


@contextmanager
def open_bag(path: str | Path) -> Iterator[Bag]:
    """Open any bag for reading, or raise ``BagError``; messages are deserialized with
    the bag's own type definitions, or Jazzy's for bags recorded without them (rosbag2 < Iron).

    A bag rosbags refuses as damaged (cut off: no MCAP footer, no ROS 1 index, SQLite pages
    missing) is read up to the damage instead (``frisicp_ros.bag.salvage``); its ``damage``
    attribute says what was lost (:func:`damage_of`).
    """
    path = Path(path)
    paths = bag_paths(path)
    mcap = mcap_storage(path)
    reader: Bag
    try:
        if mcap is not None:
            reader = McapBag(mcap)
        else:
            reader = AnyReader(paths, default_typestore=get_typestore(Stores.ROS2_JAZZY))
            reader.open()
    except Exception as err:  # noqa: BLE001 - sqlite3, mcap, yaml, struct, lz4... all mean "unreadable"
        from frisicp_ros.bag.salvage import salvage  # only for a damaged file

        salvaged = salvage(path)
        if salvaged is None:
            raise BagError(f"{path}: cannot open the bag ({describe(err)}){repair_hint(err)}") from None
        reader = salvaged
    try:
        if reader.message_count == 0:
            raise BagError(f"{path}: the bag holds no messages")
        yield reader
    finally:
        # Closing a corrupt file may fail again; there is nothing left to save.
        with contextlib.suppress(Exception):
            reader.close()


def mcap_storage(path: Path) -> Path | None:
    """The MCAP file to read with mcap's reader: a ``.mcap`` file, or a rosbag2 folder's storage
    file when it has one and that is MCAP (several split files: rosbags' reader, unchecked)."""
    if not path.is_dir():
        return path if path.suffix == ".mcap" else None
    storage = [p for p in path.iterdir() if p.suffix in (".mcap", ".db3")]
    return storage[0] if len(storage) == 1 and storage[0].suffix == ".mcap" else None


def damage_of(reader: Bag) -> str | None:
    """What made the bag unreadable past some point (None: an intact bag)."""
    damage = getattr(reader, "damage", None)  # a SalvagedBag's
    if damage:
        return f"the bag is damaged: {damage}; its {reader.message_count} messages before that were read"
    return None


def topic_summaries(reader: Bag) -> list[TopicSummary]:
    """Topics sorted by name with their type and message count."""
    return [
        TopicSummary(name, info.msgtype or "(several types)", info.msgcount)
        for name, info in sorted(reader.topics.items())
    ]


def pointcloud2_topics(reader: Bag) -> list[str]:
    return [topic.name for topic in topic_summaries(reader) if topic.is_pointcloud2]


def require_pointcloud2_topic(reader: Bag, topic: str) -> None:
    """Raise ``BagError`` unless ``topic`` is in the bag and carries PointCloud2 messages."""
    topics = {summary.name: summary for summary in topic_summaries(reader)}
    if topic not in topics:
        clouds = pointcloud2_topics(reader)
        listing = ", ".join(clouds) if clouds else "none"
        raise BagError(f"topic {topic} is not in the bag; its PointCloud2 topics: {listing}")
    if not topics[topic].is_pointcloud2:
        raise BagError(f"topic {topic} carries {topics[topic].msgtype}, not {POINTCLOUD2}")
    if topics[topic].count == 0:
        raise BagError(f"topic {topic} has no messages in the bag")
    for connection in reader.connections:
        digest = getattr(connection, "digest", "")
        if connection.topic == topic and _ROS1_MD5.fullmatch(digest) and digest != _pointcloud2_md5():
            raise BagError(
                f"topic {topic}: its ROS 1 connection declares md5sum {digest}, but"
                f" sensor_msgs/PointCloud2 has {_pointcloud2_md5()}: another message definition under"
                " that name, or a damaged connection header"
            )


_ROS1_MD5 = re.compile("[0-9a-f]{32}")  # rosbag2 connections carry "" or a RIHS01_ type hash


@functools.cache
def _pointcloud2_md5() -> str:
    return get_typestore(Stores.ROS1_NOETIC).generate_msgdef(POINTCLOUD2)[1]


def read_messages(reader: Bag, topics: Sequence[str]) -> Iterator[BagMessage]:
    """Messages of ``topics`` in bag order.

    A message that fails to deserialize is yielded with its ``error`` (the caller decides);
    a failure of the storage itself (a truncated file, a corrupt chunk) ends the iteration with
    a ``BagError`` that says after which message it happened.
    """
    connections = [c for c in reader.connections if c.topic in topics]
    index = -1
    last = "before the first message"
    messages = reader.messages(connections=connections)
    while True:
        try:
            connection, stamp_ns, raw = next(messages)
        except StopIteration:
            return
        except Exception as err:  # noqa: BLE001 - storage back ends raise many types on damage
            raise BagError(f"the bag is damaged {last}: {describe(err)}") from None
        index += 1
        last = f"after message {index} ({connection.topic} at bag time {stamp_ns} ns)"
        try:
            message = reader.deserialize(raw, connection.msgtype)
        except Exception as err:  # noqa: BLE001 - malformed CDR raises AnyReaderError, struct, index...
            yield BagMessage(index, connection.topic, stamp_ns, None, describe(err))
            continue
        yield BagMessage(index, connection.topic, stamp_ns, message)


def repair_hint(err: BaseException) -> str:
    # rosbags needs an MCAP's footer; a recording cut off by a crash or full disk has none.
    if "end magic" in str(err):
        return (
            "; the MCAP file is incomplete (a recording that was cut off?): "
            "`mcap recover IN -o OUT` (the mcap CLI) restores what it holds"
        )
    return ""


def describe(err: BaseException) -> str:
    text = str(err).strip()
    return f"{type(err).__name__}: {text}" if text else type(err).__name__
