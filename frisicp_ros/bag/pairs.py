"""The (model, data) cloud pairs of a bag, in bag order, paired exactly as the node pairs them.

Messages are read with ``frisicp_ros.bag.reader``, paired by the shared
``frisicp_ros.stream.pairing.Pairer`` on their header stamps, and handed on as
:class:`PlainCloud`: the PointCloud2 fields as plain picklable values. rosbags' message classes
are generated at run time and do not unpickle in a worker process; PlainCloud does, shares the
bytes of the original message (no copy), and is duck-type compatible with ``pointcloud2`` and
``pipeline`` (``header.stamp``, ``header.frame_id``, ``fields[i].name`` ...).

So the pipeline and ``aligned_cloud`` must read only what PlainCloud carries: anything new they
need from a message has to be added to :meth:`PlainCloud.from_message` (and ``layout_of``) too;
the bag mode's tests fail otherwise.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from frisicp_ros.bag.reader import BagError, damage_of, read_messages
from frisicp_ros.stream.pairing import Pairer
from frisicp_ros.stream.pointcloud2 import CloudParts, layout_of
from frisicp_ros.stream.settings import PipelineSettings
from frisicp_ros.stream.stamps import stamp_ns


@dataclass(frozen=True)
class Stamp:
    sec: int
    nanosec: int


@dataclass(frozen=True)
class Header:
    stamp: Stamp
    frame_id: str


@dataclass(frozen=True)
class PlainCloud(CloudParts):
    """A PointCloud2 as plain values: the shared CloudParts plus the header."""

    header: Header

    @classmethod
    def from_message(cls, msg: Any) -> PlainCloud:
        """Copy the scalar fields of a deserialized PointCloud2; ``data`` is shared, not copied."""
        stamp = msg.header.stamp
        return cls(
            header=Header(Stamp(int(stamp.sec), int(stamp.nanosec)), str(msg.header.frame_id)),
            data=np.asarray(msg.data, dtype=np.uint8),
            **layout_of(msg),
        )

    @property
    def stamp_ns(self) -> int:
        return stamp_ns(self)


class RepeatCounter:
    """Numbers the messages of a topic that follow each other at the same bag time (0, 1, ...).

    The client reading a whole bag and a worker reading a time range of it count alike, so the
    number names the same message in both (``frisicp_ros.bag.locate``).
    """

    def __init__(self) -> None:
        self._last: dict[str, tuple[int, int]] = {}  # topic -> (bag_ns, repeat)

    def count(self, topic: str, bag_ns: int) -> int:
        last = self._last.get(topic)
        repeat = last[1] + 1 if last is not None and last[0] == bag_ns else 0
        self._last[topic] = (bag_ns, repeat)
        return repeat


@dataclass(frozen=True)
class StampedCloud:
    bag_ns: int  # receive time in the bag
    ordinal: int  # 0-based position among the messages of its topic
    cloud: PlainCloud
    # Earlier messages of its topic at the same bag time: with ``bag_ns`` this finds the message
    # again by a time-range read (frisicp_ros.bag.locate), which cannot count ordinals.
    repeat: int = 0


@dataclass(frozen=True)
class BagPair:
    index: int  # 0-based, in bag order
    model: StampedCloud
    data: StampedCloud

    @property
    def model_cloud(self) -> PlainCloud:
        return self.model.cloud

    @property
    def data_cloud(self) -> PlainCloud:
        return self.data.cloud


@dataclass
class PairReading:
    """Iterates the pairs; afterwards ``stopped`` says why reading ended early (None: bag end)."""

    reader: Any  # an open rosbags AnyReader
    model_topic: str
    data_topic: str
    pairer: Pairer[StampedCloud, StampedCloud]
    stopped: str | None = None
    data_clouds: int = 0  # data messages read so far
    model_clouds: int = 0
    repeats: RepeatCounter = field(default_factory=lambda: RepeatCounter())

    @classmethod
    def paired_as(
        cls, settings: PipelineSettings, reader: Any, model_topic: str, data_topic: str
    ) -> PairReading:
        """The pairs of two topics, paired by ``settings.pairing`` as the node pairs them."""
        pairer: Pairer[StampedCloud, StampedCloud] = Pairer(settings.pairing, settings.sync_tolerance)
        return cls(reader, model_topic, data_topic, pairer)

    def __iter__(self) -> Iterator[BagPair]:
        index = 0
        try:
            for message in read_messages(self.reader, [self.model_topic, self.data_topic]):
                if message.error is not None:
                    self.stopped = (
                        f"message {message.index} ({message.topic} at bag time "
                        f"{message.stamp_ns} ns) cannot be decoded: {message.error}"
                    )
                    return
                is_data = message.topic == self.data_topic
                ordinal = self.data_clouds if is_data else self.model_clouds
                repeat = self.repeats.count(message.topic, message.stamp_ns)
                try:
                    plain = PlainCloud.from_message(message.message)
                    cloud = StampedCloud(message.stamp_ns, ordinal, plain, repeat)
                except (AttributeError, TypeError, ValueError) as err:
                    self.stopped = (
                        f"message {message.index} ({message.topic} at bag time "
                        f"{message.stamp_ns} ns) is not a usable PointCloud2: {err}"
                    )
                    return
                if is_data:
                    self.data_clouds += 1
                    pairs = self.pairer.add_data(cloud.cloud.stamp_ns, cloud)
                else:
                    self.model_clouds += 1
                    pairs = self.pairer.add_model(cloud.cloud.stamp_ns, cloud)
                for model, data in pairs:
                    yield BagPair(index, model, data)
                    index += 1
        except BagError as err:
            self.stopped = str(err)
            return
        self.stopped = damage_of(self.reader)  # a damaged bag read up to the damage
