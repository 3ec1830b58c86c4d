"""MCAP files through the ``mcap`` package's public readers, with every chunk's CRC checked.

rosbags' MCAP reader checks no CRC: bytes flipped on disk inside a chunk decoded to clouds of
garbage and ``frisicp bag`` exited 0. :class:`McapBag` reads a whole file with
``mcap.reader.make_reader(stream, validate_crcs=True)``: the summary gives the topics and counts
at once, and each chunk's CRC is checked when the chunk is read; a mismatch ends the reading
there like any damage (``reader.read_messages``: the pairs before it are kept, exit 1). A file
without summary or chunk index (allowed by the format) is counted, and then read, front to back
by the same package's ``StreamReader``, which also checks the data section's CRC.

:func:`scan` reads a cut file record by record for ``salvage`` (mcap's ``StreamReader``, CRCs
checked), plus the whole records at the start of a cut uncompressed chunk.

Messages are deserialized by rosbags' type system from the file's own schemas (``ros2msg``,
``ros2idl``), or with Jazzy's types when it has none, as rosbags' ``AnyReader`` does.
"""

from __future__ import annotations

import struct
from collections import Counter
from collections.abc import Iterator, Sequence
from io import BytesIO
from pathlib import Path
from typing import Any

from mcap.exceptions import McapError
from mcap.reader import SeekingReader
from mcap.records import Channel, Footer, Message, Schema
from mcap.stream_reader import StreamReader
from rosbags.typesys import Stores

from frisicp_ros.bag.connections import Connection, Damage, Raw, TopicInfo, topic_infos, typestore_for

MAGIC = b"\x89MCAP0\r\n"
_CHUNK = 0x06


class McapBag:
    """An intact MCAP file, read like rosbags' ``AnyReader`` (the parts frisicp uses)."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self._stream = path.open("rb")
        try:
            self._open()
        except BaseException:
            self._stream.close()
            raise

    def _open(self) -> None:
        reader = SeekingReader(self._stream, validate_crcs=True)
        summary = reader.get_summary()
        statistics = summary.statistics if summary is not None else None
        self._indexed = summary is not None and statistics is not None and bool(summary.chunk_indexes)
        if summary is not None and statistics is not None and self._indexed:
            self._reader: SeekingReader | None = reader
            schemas = summary.schemas
            self.connections = [_connection(channel, schemas) for channel in summary.channels.values()]
            counts = Counter(statistics.channel_message_counts)
            times = (statistics.message_start_time, statistics.message_end_time)
        else:  # no summary or no chunk index: read front to back (raises on damage)
            self._reader = None
            self.connections, counts, times = _count(self._linear())
        self.topics: dict[str, TopicInfo] = topic_infos(self.connections, counts)
        self.message_count = sum(counts.values())
        self.start_time, self.end_time = (times[0], times[1] + 1) if self.message_count else (0, 0)
        self._by_id = {c.id: c for c in self.connections}
        typestore = typestore_for(self.connections, Stores.ROS2_JAZZY)
        self._deserialize = typestore.deserialize_cdr

    def messages(self, connections: Sequence[Connection] | None = None) -> Iterator[Raw]:
        """The messages of ``connections`` (default all) in log-time order; a CRC mismatch or any
        damage raises from here, where the damaged chunk is read."""
        wanted = {c.id for c in (connections if connections is not None else self.connections)}
        topics = sorted({c.topic for c in self.connections if c.id in wanted})
        if self._reader is None:
            for item in self._linear():
                if not isinstance(item, Connection) and item[0].id in wanted:
                    yield item
            return
        for _, channel, message in self._reader.iter_messages(topics=topics, log_time_order=True):
            if channel.id in wanted:
                yield self._by_id[channel.id], message.log_time, message.data

    def _linear(self) -> Iterator[Connection | Raw]:
        self._stream.seek(0)
        schemas: dict[int, Schema] = {}
        channels: dict[int, Connection] = {}
        for record in StreamReader(self._stream, validate_crcs=True).records:
            yield from _items(record, schemas, channels)

    def deserialize(self, raw: bytes, msgtype: str) -> Any:
        return self._deserialize(raw, msgtype)

    def close(self) -> None:
        self._stream.close()


def scan(path: Path) -> Iterator[Connection | Raw]:
    """The records of a possibly cut MCAP file, from its start, for ``salvage``: each chunk only if
    its CRC holds, and the whole records at the start of a cut uncompressed chunk. Ends with
    :class:`Damage` saying where, or normally at the footer (the file is not cut)."""
    schemas: dict[int, Schema] = {}
    channels: dict[int, Connection] = {}
    with path.open("rb") as stream:
        records = StreamReader(stream, validate_crcs=True).records
        good = len(MAGIC)  # the end of the last whole record
        while True:
            try:
                record = next(records)
            except StopIteration:
                return
            except Exception as err:  # noqa: BLE001 - mcap raises EndOfFile, CRC, struct, value errors
                yield from _cut_chunk(path, good, schemas, channels)
                raise Damage(f"the file is damaged or cut off after byte {good} ({_describe(err)})") from None
            if isinstance(record, Footer):
                return
            good = stream.tell()  # a chunk's records come out once the whole chunk is read
            yield from _items(record, schemas, channels)


def _cut_chunk(
    path: Path, start: int, schemas: dict[int, Schema], channels: dict[int, Connection]
) -> Iterator[Connection | Raw]:
    """The whole records at the start of a chunk cut off at the end of the file, if the chunk is
    uncompressed (a compressed one cannot be decoded in part; and no CRC can vouch for either)."""
    with path.open("rb") as stream:
        stream.seek(start)
        head = stream.read(9)
        if len(head) < 9 or head[0] != _CHUNK:
            return
        body = stream.read()
    try:
        record = BytesIO(body)
        record.read(28)  # start time, end time, uncompressed size, CRC
        (length,) = struct.unpack("<I", record.read(4))
        if record.read(length) != b"":
            return  # compressed
        record.read(8)  # the records' length, as written before the cut
        inner = StreamReader(BytesIO(record.read()), skip_magic=True).records
        for found in inner:
            yield from _items(found, schemas, channels)
    except (McapError, struct.error, ValueError, UnicodeDecodeError):
        return  # the first incomplete record: the cut


def _items(
    record: object, schemas: dict[int, Schema], channels: dict[int, Connection]
) -> Iterator[Connection | Raw]:
    if isinstance(record, Schema):
        schemas[record.id] = record
    elif isinstance(record, Channel) and record.id not in channels:
        channels[record.id] = _connection(record, schemas)
        yield channels[record.id]
    elif isinstance(record, Message) and record.channel_id in channels:
        yield channels[record.channel_id], record.log_time, record.data


def _connection(channel: Channel, schemas: dict[int, Schema]) -> Connection:
    schema = schemas.get(channel.schema_id)
    if schema is None:
        return Connection(channel.id, channel.topic, "")
    return Connection(channel.id, channel.topic, schema.name, schema.encoding, schema.data.decode())


def _count(items: Iterator[Connection | Raw]) -> tuple[list[Connection], Counter[int], tuple[int, int]]:
    connections: list[Connection] = []
    counts: Counter[int] = Counter()
    first, last = 0, 0
    for item in items:
        if isinstance(item, Connection):
            connections.append(item)
            continue
        stamp = item[1]
        first, last = (stamp, stamp) if not counts else (min(first, stamp), max(last, stamp))
        counts[item[0].id] += 1
    return connections, counts, (first, last)


def _describe(err: BaseException) -> str:
    text = str(err).strip()
    return f"{type(err).__name__}: {text}" if text else type(err).__name__
