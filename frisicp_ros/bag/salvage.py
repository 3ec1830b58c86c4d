"""Reading a damaged bag up to the damage: what rosbags will not open, record by record.

A recording cut off by a crash or a full disk (or copied in part) lacks what rosbags' readers
need at open: an MCAP's footer and summary, a ROS 1 bag's index (both at the end of the file), a
consistent SQLite file. Yet the messages before the cut are intact. :func:`salvage` reads them
from the start of the file, in file order, and stops at the first record that is incomplete or
fails its check (an MCAP chunk's CRC, SQLite's page structure), saying where in ``damage``.

The result duck-types the parts of rosbags' ``AnyReader`` that frisicp uses (``topics``,
``connections``, ``messages``, ``deserialize``, the time span), so the bag mode, ``bag-info``
and the node's replay read a damaged bag like any other and then report the damage.
"""

from __future__ import annotations

import functools
import shutil
import sqlite3
import struct
import tempfile
from collections import Counter
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from io import BytesIO
from pathlib import Path
from typing import Any, BinaryIO

from rosbags.rosbag1.reader import Header, ReaderError, decompressors, normalize
from rosbags.rosbag2.storage_mcap import decompress
from rosbags.typesys import Stores, get_typestore
from rosbags.typesys.msg import normalize_msgtype

MCAP_MAGIC = b"\x89MCAP0\r\n"
ROS1_MAGIC = b"#ROSBAG V2.0\n"
SQLITE_MAGIC = b"SQLite format 3\x00"


@dataclass(frozen=True)
class Connection:
    id: int
    topic: str
    msgtype: str


@dataclass(frozen=True)
class TopicInfo:
    msgtype: str
    msgcount: int


Raw = tuple[Connection, int, bytes]  # connection, bag time (ns), serialized message


class Damage(Exception):  # noqa: N818 - a finding, raised to stop a scan
    """Where and how the readable part of the file ends."""


class SalvagedBag:
    """The intact messages of a damaged bag file; ``damage`` says what ended the reading."""

    def __init__(self, path: Path, scan: Callable[[], Iterator[Connection | Raw]], ros1: bool) -> None:
        self.path = path
        self._scan = scan
        self._typestore = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_JAZZY)
        self._deserialize = self._typestore.deserialize_ros1 if ros1 else self._typestore.deserialize_cdr
        self.connections: list[Connection] = []
        self.damage = "the file ends early"
        counts: Counter[int] = Counter()
        stamps: list[int] = []
        try:
            for item in scan():
                if isinstance(item, Connection):
                    self.connections.append(item)
                else:
                    counts[item[0].id] += 1
                    stamps.append(item[1])
        except Damage as damage:
            self.damage = str(damage)
        self.message_count = sum(counts.values())
        self.start_time = min(stamps, default=0)
        self.end_time = max(stamps, default=-1) + 1
        self.topics = {
            c.topic: TopicInfo(c.msgtype, sum(counts[d.id] for d in self.connections if d.topic == c.topic))
            for c in self.connections
        }

    def messages(self, connections: list[Connection] | None = None) -> Iterator[Raw]:
        """The intact messages of ``connections`` (default all) in file order; the damage ends
        the iteration quietly (it was found and described at open)."""
        wanted = {c.id for c in (connections if connections is not None else self.connections)}
        try:
            for item in self._scan():
                if not isinstance(item, Connection) and item[0].id in wanted:
                    yield item
        except Damage:
            return

    def deserialize(self, raw: bytes, msgtype: str) -> Any:
        return self._deserialize(raw, msgtype)

    def close(self) -> None:
        """Nothing to release: every scan opens and closes the file itself."""


def salvage(path: Path) -> SalvagedBag | None:
    """The intact part of a damaged bag file (a rosbag2 folder: its one storage file), or None
    when the file is no bag this module knows or nothing in it can be read."""
    if path.is_dir():
        storage = sorted(p for p in path.iterdir() if p.suffix in (".mcap", ".db3"))
        if len(storage) != 1:
            return None
        path = storage[0]
    try:
        with path.open("rb") as stream:
            start = stream.read(16)
    except OSError:
        return None
    scans = {MCAP_MAGIC: _mcap_records, ROS1_MAGIC: _ros1_records, SQLITE_MAGIC: _sqlite_records}
    for magic, records in scans.items():
        if start.startswith(magic):
            try:
                bag = SalvagedBag(path, functools.partial(records, path), ros1=magic == ROS1_MAGIC)
            except Exception:  # noqa: BLE001 - a salvage attempt never raises: the caller reports
                return None  # rosbags' reason for refusing the file
            return bag if bag.message_count else None
    return None


# --- MCAP: records from the file's start; a chunk is used only if its CRC holds ------------------


def _mcap_records(path: Path) -> Iterator[Connection | Raw]:
    schemas: dict[int, str] = {}
    channels: dict[int, Connection] = {}
    with path.open("rb") as stream:
        if stream.read(8) != MCAP_MAGIC:
            raise Damage("no MCAP magic")
        while True:
            at = stream.tell()
            op = stream.read(1)
            if not op:
                raise Damage(f"the file ends at byte {at} without the MCAP footer")
            length = _uint64(_read_exact(stream, 8, at))
            body = stream.read(length)
            if len(body) < length:
                if op[0] == 0x06:  # the messages of an uncompressed chunk before the cut are whole
                    yield from _mcap_cut_chunk(body, schemas, channels)
                raise Damage(f"the record at byte {at} is cut off ({len(body)} of {length} bytes)")
            if op[0] == 0x02:  # footer: the data section is complete
                return
            try:
                if op[0] == 0x06:
                    items = list(_mcap_chunk(body, schemas, channels))
                else:
                    items = list(_mcap_record(op[0], body, schemas, channels))
            except (ReaderError, struct.error, IndexError, ValueError) as err:
                raise Damage(f"the record at byte {at} is damaged ({err})") from None
            yield from items


def _mcap_cut_chunk(
    body: bytes, schemas: dict[int, str], channels: dict[int, Connection]
) -> Iterator[Connection | Raw]:
    """The complete records at the start of a cut-off chunk, if it is uncompressed."""
    record = BytesIO(body)
    try:
        record.read(28)
        if _string(record) != "":
            return  # compressed: nothing before the cut can be decoded on its own
        record.read(8)
        while True:
            header = record.read(9)
            if len(header) < 9:
                return
            length = _uint64(header[1:])
            data = record.read(length)
            if len(data) < length:
                return
            yield from _mcap_record(header[0], data, schemas, channels)
    except (struct.error, UnicodeDecodeError, IndexError):
        return


def _mcap_chunk(
    body: bytes, schemas: dict[int, str], channels: dict[int, Connection]
) -> Iterator[Connection | Raw]:
    record = BytesIO(body)
    _, _, size, crc = struct.unpack("<QQQI", record.read(28))
    compression = _string(record)
    compressed = record.read(_uint64(record.read(8)))
    records = BytesIO(decompress(compressed, compression, size, crc))
    items: list[Connection | Raw] = []  # decoded whole first: a chunk is used entirely or not at all
    while records.tell() < size:
        op = records.read(1)[0]
        length = _uint64(records.read(8))
        items.extend(_mcap_record(op, records.read(length), schemas, channels))
    yield from items


def _mcap_record(
    op: int, body: bytes, schemas: dict[int, str], channels: dict[int, Connection]
) -> Iterator[Connection | Raw]:
    record = BytesIO(body)
    if op == 0x03:  # schema
        (schema_id,) = struct.unpack("<H", record.read(2))
        schemas[schema_id] = _string(record)
    elif op == 0x04:  # channel
        channel_id, schema_id = struct.unpack("<HH", record.read(4))
        topic = _string(record)
        channel = Connection(channel_id, topic, schemas.get(schema_id, ""))
        if channel_id not in channels:
            channels[channel_id] = channel
            yield channel
    elif op == 0x05:  # message
        channel_id, _, log_time, _ = struct.unpack("<HIQQ", record.read(22))
        if channel_id in channels:
            yield channels[channel_id], log_time, record.read()


# --- ROS 1: the chunks after the bag header, until one is incomplete ------------------------------


def _ros1_records(path: Path) -> Iterator[Connection | Raw]:
    connections: dict[int, Connection] = {}
    with path.open("rb") as stream:
        stream.readline()  # the version line, checked by salvage()
        try:
            Header.read(stream)
            _read_exact(stream, _uint32(stream.read(4)), stream.tell())  # the bag header's padding
        except ReaderError as err:
            raise Damage(f"the bag header is damaged ({err})") from None
        while True:
            at = stream.tell()
            if not stream.read(1):
                raise Damage(f"the file ends at byte {at}, before the bag's index")
            stream.seek(at)
            try:
                header = Header.read(stream)
                length = _uint32(stream.read(4))
                data = stream.read(length)
                op = header.get_uint8("op")
                if len(data) < length:
                    if op == 0x05 and header.get_string("compression") == "none":
                        yield from _ros1_chunk(data, connections, cut=True)  # whole records before the cut
                    raise Damage(f"the record at byte {at} is cut off ({len(data)} of {length} bytes)")
                if op == 0x05:  # chunk
                    chunk = decompressors[header.get_string("compression")](data)
                    items = list(_ros1_chunk(chunk, connections))
                else:
                    items = []  # index data, and the index section's records at the end
            except (ReaderError, KeyError, ValueError, OSError, struct.error) as err:
                raise Damage(f"the record at byte {at} is damaged or incomplete ({err})") from None
            yield from items


def _ros1_chunk(
    chunk: bytes, connections: dict[int, Connection], cut: bool = False
) -> Iterator[Connection | Raw]:
    """The records of a chunk; of a ``cut`` one, those before the first incomplete record."""
    records = BytesIO(chunk)
    while records.tell() < len(chunk):
        try:
            header = Header.read(records)
            length = _uint32(records.read(4))
        except (ReaderError, Damage):
            if cut:
                return
            raise
        data = records.read(length)
        if len(data) < length and cut:
            return
        op = header.get_uint8("op")
        if op == 0x07:  # connection
            fields = Header.read(BytesIO(struct.pack("<I", len(data)) + data))
            conn = header.get_uint32("conn")
            if conn not in connections:
                topic = normalize(header.get_string("topic"))
                connections[conn] = Connection(conn, topic, normalize_msgtype(fields.get_string("type")))
                yield connections[conn]
        elif op == 0x02:  # message data
            yield connections[header.get_uint32("conn")], header.get_time("time"), data


# --- SQLite (rosbag2 .db3): rows in insertion order until a page is missing ------------------------


def _sqlite_records(path: Path) -> Iterator[Connection | Raw]:
    """A copy whose header states the pages that are really there (a cut file's header still
    counts the lost ones, and SQLite then refuses even its schema); rows until a missing page.

    One query per row: Python's cursor steps to the next row before it returns the current one,
    and drops the current one when that step fails, so a plain cursor lost the last intact row
    before the damage (one pair fewer than lay before the cut).
    """
    with tempfile.TemporaryDirectory(prefix="frisicp-salvage-") as folder:
        copy = Path(folder) / path.name
        shutil.copyfile(path, copy)
        _fit_sqlite_header(copy)
        database = sqlite3.connect(f"file:{copy}?mode=ro", uri=True)
        try:
            try:
                rows = database.execute("SELECT id, name, type FROM topics").fetchall()
            except sqlite3.DatabaseError as err:
                raise Damage(f"its topic table is unreadable ({err})") from None
            connections = {row[0]: Connection(row[0], str(row[1]), str(row[2])) for row in rows}
            yield from connections.values()
            last = -(2**63)
            while True:
                try:
                    row = database.execute(_NEXT_ROW, (last,)).fetchone()
                except sqlite3.DatabaseError as err:
                    raise Damage(f"the message table is damaged after row {last} ({err})") from None
                if row is None:
                    raise Damage("its pages end early")  # all rows read, yet the file was refused
                last = row[0]
                if row[1] in connections:
                    yield connections[row[1]], int(row[2]), bytes(row[3])
        finally:
            database.close()


_NEXT_ROW = "SELECT id, topic_id, timestamp, data FROM messages WHERE id > ? ORDER BY id LIMIT 1"


def _fit_sqlite_header(path: Path) -> None:
    with path.open("r+b") as stream:
        header = stream.read(100)
        page_size = struct.unpack(">H", header[16:18])[0]
        page_size = 65536 if page_size == 1 else page_size
        pages = path.stat().st_size // page_size
        stream.truncate(pages * page_size)
        stream.seek(28)
        stream.write(struct.pack(">I", pages))


# --- helpers ------------------------------------------------------------------------------------


def _read_exact(stream: BinaryIO, size: int, at: int) -> bytes:
    data = stream.read(size)
    if len(data) != size:
        raise Damage(f"the record at byte {at} is cut off ({len(data)} of {size} bytes)")
    return data


def _uint64(data: bytes) -> int:
    return int(struct.unpack("<Q", data)[0])


def _uint32(data: bytes) -> int:
    if len(data) != 4:
        raise Damage("the file ends inside a record")
    return int(struct.unpack("<I", data)[0])


def _string(record: BytesIO) -> str:
    (length,) = struct.unpack("<I", record.read(4))
    return record.read(length).decode()
