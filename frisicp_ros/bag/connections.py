"""What frisicp's own bag readers (``mcap_bag``, ``salvage``) hand out instead of rosbags' objects:
connections, topic summaries, a typestore built from the message definitions a file carries, and
the ``Damage`` a scan of a damaged file stops with.

A leaf of the bag package: rosbags' public type system only.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Iterable
from dataclasses import dataclass
from typing import TYPE_CHECKING

from rosbags.typesys import Stores, get_types_from_idl, get_types_from_msg, get_typestore

if TYPE_CHECKING:
    from rosbags.typesys.store import Typestore

IDL_SEPARATOR = "=" * 80 + "\n"


class Damage(Exception):  # noqa: N818 - a finding, raised to stop a scan
    """Where and how the readable part of a file ends."""


@dataclass(frozen=True)
class Connection:
    """A topic's channel in a file: ``encoding`` and ``definition`` are its message definition as
    stored (MCAP schema: ``ros2msg``/``ros2idl``; ROS 1: ``ros1msg``), ``digest`` a ROS 1 md5sum."""

    id: int
    topic: str
    msgtype: str
    encoding: str = ""
    definition: str = ""
    digest: str = ""


@dataclass(frozen=True)
class TopicInfo:
    msgtype: str
    msgcount: int


Raw = tuple[Connection, int, bytes]  # connection, bag time (ns), serialized message


def topic_infos(connections: Iterable[Connection], counts: Counter[int]) -> dict[str, TopicInfo]:
    """Per topic: its type and message count (over all its connections)."""
    by_topic: dict[str, list[Connection]] = {}
    for connection in connections:
        by_topic.setdefault(connection.topic, []).append(connection)
    return {
        topic: TopicInfo(group[0].msgtype, sum(counts[c.id] for c in group))
        for topic, group in by_topic.items()
    }


def typestore_for(connections: Iterable[Connection], fallback: Stores) -> Typestore:
    """A rosbags typestore with the types the connections define (as rosbags' AnyReader builds
    it), or the ``fallback`` store's types when none carries a definition."""
    types: dict[str, object] = {}
    for connection in connections:
        if connection.encoding in ("ros2msg", "ros1msg") and connection.definition:
            types.update(get_types_from_msg(connection.definition, connection.msgtype))
        elif connection.encoding == "ros2idl" and connection.definition:
            text = connection.definition
            parts = text.split(IDL_SEPARATOR)[1:] if text.startswith(f"{IDL_SEPARATOR}IDL: ") else [text]
            for part in parts:
                types.update(get_types_from_idl(part.split("\n", 1)[1] if part.startswith("IDL: ") else part))
    if not types:
        return get_typestore(fallback)
    store = get_typestore(Stores.EMPTY)
    store.register(types)  # type: ignore[arg-type]  # rosbags' Typesdict values
    return store
