"""``frisicp bag-info INPUT``: what a bag holds, and which topics ``frisicp bag`` can register."""

from __future__ import annotations

import argparse
import json
import sys

from frisicp_ros.bag.reader import BagError, damage_of, open_bag, topic_summaries
from frisicp_ros.cli.command import CommandError

NAME = "bag-info"
SUMMARY = "list a bag's topics, types and counts, marking the PointCloud2 topics"
DESCRIPTION = (
    "List the topics of a rosbag2 folder, .db3, .mcap or ROS 1 .bag file (no ROS installation needed)."
)


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("input", help="rosbag2 folder, .db3 or .mcap file, or ROS 1 .bag file")
    parser.add_argument("--json", action="store_true", help="print one JSON object")


def run(args: argparse.Namespace) -> int:
    try:
        with open_bag(args.input) as reader:
            topics = topic_summaries(reader)
            start_ns, end_ns, count = reader.start_time, reader.end_time, reader.message_count
            damage = damage_of(reader)
    except BagError as err:
        raise CommandError(str(err)) from None
    # An empty bag reports start > end (rosbags' sentinels); say 0 rather than a negative span.
    duration_sec = max(end_ns - start_ns, 0) / 1e9 if count else 0.0
    if args.json:
        print(
            json.dumps(
                {
                    "path": str(args.input),
                    "messages": count,
                    "duration_sec": duration_sec,
                    "start_ns": start_ns if count else None,
                    "topics": [
                        {"name": t.name, "type": t.msgtype, "count": t.count, "pointcloud2": t.is_pointcloud2}
                        for t in topics
                    ],
                    "damage": damage,
                }
            )
        )
        return 1 if damage else 0
    print(f"bag       {args.input}")
    print(f"messages  {count}   duration {duration_sec:.3f} s")
    if not topics:
        print("topics    none")
        return 1 if damage else 0
    name_width = max(len(t.name) for t in topics)
    type_width = max(len(t.msgtype) for t in topics)
    print(f"{'topic':<{name_width}}  {'type':<{type_width}}  {'count':>7}")
    for topic in topics:
        mark = "  <- PointCloud2" if topic.is_pointcloud2 else ""
        print(f"{topic.name:<{name_width}}  {topic.msgtype:<{type_width}}  {topic.count:>7}{mark}")
    clouds = [t.name for t in topics if t.is_pointcloud2]
    print(f"PointCloud2 topics: {', '.join(clouds) if clouds else 'none'}")
    if damage:
        print(f"frisicp bag-info: {damage} (counted above)", file=sys.stderr)
        return 1
    return 0
