"""Reading a damaged bag up to the damage: what rosbags will not open, record by record.

A recording cut off by a crash or a full disk (or copied in part) lacks what rosbags' readers
need at open: an MCAP's footer and summary, a ROS 1 bag's index (both at the end of the file), a
consistent SQLite file. Yet the messages before the cut are intact. :func:`salvage` reads them
from the start of the file, in file order, and stops at the first record that is incomplete or
fails its check (an MCAP chunk's CRC, SQLite's page structure), saying where in ``damage``. A
file read to its proper end is not cut: rosbags had another reason to refuse it, and that
reason stands (:func:`salvage` returns None).

MCAP through the ``mcap`` package (``frisicp_ros.bag.mcap_bag.scan``); ROS 1 records and SQLite
pages here, with nothing of rosbags but its public type system (its private names moved between
releases: rosbags 0.10 to 0.11.5 had no ``decompress`` where this module once imported it).

The result duck-types the parts of rosbags' ``AnyReader`` that frisicp uses (``topics``,
``connections``, ``messages``, ``deserialize``, the time span), so the bag mode, ``bag-info``
and the node's replay read a damaged bag like any other and then report the damage.
"""

from __future__ import annotations

import bz2
import functools
import shutil
import sqlite3
import struct
import tempfile
from collections import Counter
from collections.abc import Callable, Iterator
from io import BytesIO
from pathlib import Path
from typing import Any, BinaryIO

from rosbags.typesys import Stores

from frisicp_ros.bag.connections import Connection, Damage, Raw, topic_infos, typestore_for
from frisicp_ros.bag.mcap_bag import MAGIC as MCAP_MAGIC
from frisicp_ros.bag.mcap_bag import scan as mcap_records
from frisicp_ros.stream.stamps import time_ns

ROS1_MAGIC = b"#ROSBAG V2.0\n"
SQLITE_MAGIC = b"SQLite format 3\x00"


class SalvagedBag:
    """The intact messages of a damaged bag file; ``damage`` says what ended the reading (None:
    the scan reached the file's proper end)."""

    def __init__(self, path: Path, scan: Callable[[], Iterator[Connection | Raw]], ros1: bool) -> None:
        self.path = path
        self._scan = scan
        self.connections: list[Connection] = []
        self.damage: str | None = None
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
        self.topics = topic_infos(self.connections, counts)
        # ROS 1 as rosbags' readers decode it without definitions (Noetic); rosbag2 with the file's
        # own definitions (MCAP schemas), else Jazzy's.
        typestore = typestore_for(
            [] if ros1 else self.connections, Stores.ROS1_NOETIC if ros1 else Stores.ROS2_JAZZY
        )
        self._deserialize = typestore.deserialize_ros1 if ros1 else typestore.deserialize_cdr

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
    when the file is no bag this module knows, is not damaged, or nothing in it can be read."""
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
    scans = {MCAP_MAGIC: mcap_records, ROS1_MAGIC: _ros1_records, SQLITE_MAGIC: _sqlite_records}
    for magic, records in scans.items():
        if start.startswith(magic):
            try:
                bag = SalvagedBag(path, functools.partial(records, path), ros1=magic == ROS1_MAGIC)
            except Exception:  # noqa: BLE001 - a salvage attempt never raises: the caller reports
                return None  # rosbags' reason for refusing the file
            return bag if bag.damage is not None and bag.message_count else None
    return None


# --- ROS 1: the chunks after the bag header, until one is incomplete ------------------------------

_ROS1_MESSAGE, _ROS1_BAG_HEADER, _ROS1_CHUNK, _ROS1_CONNECTION = 0x02, 0x03, 0x05, 0x07
_ROS1_INDEX_SECTION = (0x06, 0x07)  # chunk info and connection records, after the last chunk


def _ros1_records(path: Path) -> Iterator[Connection | Raw]:
    connections: dict[int, Connection] = {}
    with path.open("rb") as stream:
        stream.readline()  # the version line, checked by salvage()
        header = _ros1_header(stream, stream.tell())
        if _uint8(header, "op") != _ROS1_BAG_HEADER:
            raise Damage("the bag header is damaged")
        _read_exact(stream, _uint32(stream.read(4)), stream.tell())  # the bag header's padding
        while True:
            at = stream.tell()
            if not stream.read(1):
                raise Damage(f"the file ends at byte {at}, before the bag's index")
            stream.seek(at)
            try:
                header = _ros1_header(stream, at)
                length = _uint32(stream.read(4))
                data = stream.read(length)
                op = _uint8(header, "op")
                if len(data) < length:
                    if op == _ROS1_CHUNK and _string(header, "compression") == "none":
                        yield from _ros1_chunk(data, connections, cut=True)  # whole records before the cut
                    raise Damage(f"the record at byte {at} is cut off ({len(data)} of {length} bytes)")
                if op in _ROS1_INDEX_SECTION:
                    return  # every chunk was read: the file is whole
                items = list(_ros1_chunk(_decompress(header, data), connections)) if op == _ROS1_CHUNK else []
            except (KeyError, ValueError, OSError, struct.error) as err:
                raise Damage(f"the record at byte {at} is damaged or incomplete ({err})") from None
            yield from items


def _ros1_chunk(
    chunk: bytes, connections: dict[int, Connection], cut: bool = False
) -> Iterator[Connection | Raw]:
    """The records of a chunk; of a ``cut`` one, those before the first incomplete record."""
    records = BytesIO(chunk)
    while records.tell() < len(chunk):
        try:
            header = _ros1_header(records, records.tell())
            length = _uint32(records.read(4))
        except Damage:
            if cut:
                return
            raise
        data = records.read(length)
        if len(data) < length and cut:
            return
        op = _uint8(header, "op")
        if op == _ROS1_CONNECTION:
            fields = _ros1_header(BytesIO(struct.pack("<I", len(data)) + data), 0)
            conn = _uint32(header["conn"])
            if conn not in connections:
                connections[conn] = Connection(
                    conn,
                    _topic(_string(header, "topic")),
                    _msgtype(_string(fields, "type")),
                    "ros1msg",
                    _string(fields, "message_definition") if "message_definition" in fields else "",
                    _string(fields, "md5sum") if "md5sum" in fields else "",
                )
                yield connections[conn]
        elif op == _ROS1_MESSAGE:
            sec, nanosec = struct.unpack("<II", header["time"])
            yield connections[_uint32(header["conn"])], time_ns(sec, nanosec), data


def _ros1_header(stream: BinaryIO, at: int) -> dict[str, bytes]:
    """A record header: a length, then fields each of a length and ``name=value``."""
    raw = _read_exact(stream, _uint32(stream.read(4)), at)
    fields: dict[str, bytes] = {}
    position = 0
    while position < len(raw):
        (size,) = struct.unpack_from("<I", raw, position)
        field = raw[position + 4 : position + 4 + size]
        name, equals, value = field.partition(b"=")
        if not equals or len(field) < size:
            raise Damage(f"the record header at byte {at} is damaged")
        fields[name.decode()] = value
        position += 4 + size
    return fields


def _decompress(header: dict[str, bytes], data: bytes) -> bytes:
    compression = _string(header, "compression")
    if compression == "none":
        return data
    if compression == "bz2":
        return bz2.decompress(data)
    if compression == "lz4":
        import lz4.frame  # rosbags' and mcap's dependency; ROS 1 lz4 chunks are lz4 frames

        return bytes(lz4.frame.decompress(data))
    raise ValueError(f"unknown chunk compression {compression!r}")


def _uint8(header: dict[str, bytes], name: str) -> int:
    return int(struct.unpack("<B", header[name])[0])


def _string(header: dict[str, bytes], name: str) -> str:
    return header[name].decode()


def _topic(name: str) -> str:
    """As rosbags names ROS 1 topics: no repeated or trailing slashes."""
    return "/" * name.startswith("/") + "/".join(part for part in name.split("/") if part)


def _msgtype(name: str) -> str:
    """A ROS 1 type name in ROS 2 spelling, as rosbags gives it: sensor_msgs/msg/PointCloud2."""
    package, _, message = name.partition("/")
    return f"{package}/msg/{message.rpartition('/')[2]}"


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


def _uint32(data: bytes) -> int:
    if len(data) != 4:
        raise Damage("the file ends inside a record")
    return int(struct.unpack("<I", data)[0])
