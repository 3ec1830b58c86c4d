"""Where a pair's clouds are in a bag, and reading them back from there on another machine.

A cluster task carries locators instead of clouds: a bag path on a filesystem the workers share
and, per cloud, its topic, bag time and header stamp (hundreds of bytes, where the clouds are
hundreds of kilobytes that would all pass through the scheduler). The worker opens the bag,
reads each topic's messages over the bag-time range its locators span and rebuilds the very
:class:`BagPair` the client read: same messages, same decoding (``PlainCloud.from_message``), so
the registration sees the same numbers wherever it runs.

Every way this can go wrong on a worker is a :class:`BagError` naming the worker's view: the
bag missing or unreadable there, a different file at that path (its size differs from the
client's), a located message missing or not the one the client read (another header stamp).
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from rosbags.highlevel import AnyReader

from frisicp_ros.bag.pairs import BagPair, PlainCloud, RepeatCounter, StampedCloud
from frisicp_ros.bag.reader import Bag, BagError, describe, open_bag


def bag_size(path: Path) -> int:
    """Bytes of the bag: the file, or the files of a rosbag2 folder (what the workers compare)."""
    if path.is_dir():
        return sum(p.stat().st_size for p in path.iterdir() if p.is_file())
    return path.stat().st_size


@dataclass(frozen=True)
class BagSource:
    """A bag as the client opened it: absolute path, size and the two topics paired."""

    path: str
    size: int
    model_topic: str
    data_topic: str

    @classmethod
    def of(cls, path: str | Path, model_topic: str, data_topic: str) -> BagSource:
        absolute = Path(path).resolve()
        return cls(str(absolute), bag_size(absolute), model_topic, data_topic)

    def check_same_bag(self) -> None:
        """Raise ``BagError`` unless this machine sees a bag of the client's size at the path."""
        try:
            size = bag_size(Path(self.path))
        except OSError as err:
            raise BagError(f"{self.path}: cannot read it here: {err.strerror or err}") from None
        if size != self.size:
            raise BagError(
                f"{self.path} holds {size} bytes here, {self.size} where the client read it: "
                "not the same bag (is the shared filesystem mounted at the same path everywhere?)"
            )


@dataclass(frozen=True)
class CloudLocator:
    topic: str
    bag_ns: int
    repeat: int  # see StampedCloud.repeat
    ordinal: int
    header_stamp_ns: int


@dataclass(frozen=True)
class PairLocator:
    index: int
    model: CloudLocator
    data: CloudLocator


def locate(pair: BagPair, source: BagSource) -> PairLocator:
    def cloud(stamped: StampedCloud, topic: str) -> CloudLocator:
        return CloudLocator(topic, stamped.bag_ns, stamped.repeat, stamped.ordinal, stamped.cloud.stamp_ns)

    return PairLocator(pair.index, cloud(pair.model, source.model_topic), cloud(pair.data, source.data_topic))


def read_pairs(source: BagSource, locators: Sequence[PairLocator]) -> list[BagPair]:
    """The pairs at ``locators``, read from ``source`` on this machine (or ``BagError``)."""
    source.check_same_bag()
    wanted = [cloud for pair in locators for cloud in (pair.model, pair.data)]
    with open_bag(source.path) as reader:
        clouds = _read_clouds(reader, wanted)

    def stamped(at: CloudLocator) -> StampedCloud:
        return StampedCloud(at.bag_ns, at.ordinal, clouds[at], at.repeat)

    return [BagPair(at.index, stamped(at.model), stamped(at.data)) for at in locators]


def _read_clouds(reader: Bag, wanted: Sequence[CloudLocator]) -> dict[CloudLocator, PlainCloud]:
    found: dict[CloudLocator, PlainCloud] = {}
    for topic in sorted({at.topic for at in wanted}):
        of_topic = {(at.bag_ns, at.repeat): at for at in wanted if at.topic == topic}
        start, stop = min(of_topic)[0], max(of_topic)[0] + 1
        repeats = RepeatCounter()
        for connection, bag_ns, raw in _messages_between(reader, topic, start, stop):
            at = of_topic.get((bag_ns, repeats.count(topic, bag_ns)))
            if at is None:
                continue
            found[at] = _decoded(reader, raw, connection.msgtype, at)
    missing = [at for at in wanted if at not in found]
    if missing:
        first = missing[0]
        raise BagError(f"the message of {first.topic} at bag time {first.bag_ns} ns is not in the bag here")
    return found


def _messages_between(reader: Bag, topic: str, start: int, stop: int) -> Iterator[tuple[Any, int, bytes]]:
    """The topic's messages with start <= bag time < stop, in the order a whole read gives them."""
    connections = [c for c in reader.connections if c.topic == topic]
    messages: Iterator[tuple[Any, int, bytes]]
    if isinstance(reader, AnyReader):  # indexed: seeks to the range
        messages = reader.messages(connections=connections, start=start, stop=stop)
    else:  # a salvaged bag is read from its start
        messages = reader.messages(connections=connections)
    try:
        for connection, bag_ns, raw in messages:
            if start <= bag_ns < stop:
                yield connection, bag_ns, raw
    except Exception as err:  # noqa: BLE001 - storage back ends raise many types on damage
        raise BagError(f"the bag is damaged here: {describe(err)}") from None


def _decoded(reader: Bag, raw: bytes, msgtype: str, at: CloudLocator) -> PlainCloud:
    try:
        cloud = PlainCloud.from_message(reader.deserialize(raw, msgtype))
    except Exception as err:  # noqa: BLE001 - whatever decoding raises, the client decoded it
        raise BagError(f"the message of {at.topic} at bag time {at.bag_ns} ns: {describe(err)}") from None
    if cloud.stamp_ns != at.header_stamp_ns:
        raise BagError(
            f"the message of {at.topic} at bag time {at.bag_ns} ns has header stamp {cloud.stamp_ns} ns "
            f"here, {at.header_stamp_ns} ns where the client read it: not the same bag"
        )
    return cloud
