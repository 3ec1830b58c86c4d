"""``frisicp bag INPUT``: register the cloud pairs of a bag offline, without ROS.

Pairs are formed and registered by the same code as the live node (``pairing``, ``pipeline``,
``outputs``). Results go to JSONL (stdout by default) as they are computed and, with
``--out-bag``, into a rosbag2 with the node's output topics. Progress and the summary go to
stderr. Exit codes: 0 the bag was read to its end (rejected or unreliable pairs are marked per
line and counted in the summary), 1 the bag stopped being readable part-way or an output failed
(results so far kept), 2 bad arguments or an unreadable bag, 130 interrupted (Ctrl-C), 143
terminated (SIGTERM) (results so far kept in both).
"""

from __future__ import annotations

import argparse
from pathlib import Path

from frisicp_ros.cli.command import CommandError
from frisicp_ros.cli.options import add_guess_options, add_options, given_values, guess_from_args
from frisicp_ros.stream.settings import PipelineSettings, Surface, settings_from

NAME = "bag"
MAX_JOBS = 256  # processes; more only exhausts memory (each holds its clouds and a KD-tree)
SUMMARY = "register the cloud pairs of a bag offline (no ROS installation needed)"
DESCRIPTION = (
    "Register every (model, data) PointCloud2 pair of a rosbag2 folder, .db3 or "
    ".mcap file, or ROS 1 .bag, paired and registered as the live node does it, with the "
    "node's defaults. One JSON line per pair on stdout (or --out), a progress bar and a "
    "summary on stderr."
)


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("input", help="rosbag2 folder, .db3 or .mcap file, or ROS 1 .bag file")
    parser.add_argument("--model-topic", required=True, help="PointCloud2 topic that stays fixed")
    parser.add_argument("--data-topic", required=True, help="PointCloud2 topic registered onto the model")
    parser.add_argument(
        "--out", default="-", metavar="FILE", help="JSONL result file, one line per pair (default: stdout)"
    )
    parser.add_argument(
        "--out-bag", metavar="DIR", help="also write a rosbag2 (mcap) with the node's output topics"
    )
    parser.add_argument(
        "--out-prefix",
        default="/frisicp",
        metavar="NS",
        help="namespace of the result bag's topics, the node's name (default %(default)s)",
    )
    parser.add_argument(
        "--jobs",
        type=int,
        default=1,
        metavar="N",
        help=f"registration processes, 1..{MAX_JOBS}; results stay in bag order. With warm start each"
        " worker warm-starts within chunks of consecutive pairs (default 1)",
    )
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    parser.add_argument(
        "--plot",
        metavar="PNG",
        help="also draw scale, rotation, RMS, registration time and every pair's verdict over the bag's"
        " time into this PNG",
    )
    add_guess_options(
        parser, "the first pair is registered around it instead of blind, and tracking follows (--jobs 1)"
    )
    add_options(parser, Surface.BAG)


def settings_from_args(args: argparse.Namespace) -> PipelineSettings:
    try:
        return settings_from(given_values(args, Surface.BAG))
    except ValueError as err:
        raise CommandError(str(err)) from None


def check_arguments(args: argparse.Namespace, settings: PipelineSettings) -> None:
    if args.model_topic == args.data_topic:
        raise CommandError("--model-topic and --data-topic must be different topics")
    if not 1 <= args.jobs <= MAX_JOBS:
        raise CommandError(f"--jobs must be in [1, {MAX_JOBS}], got {args.jobs}")
    if args.out_bag and Path(args.out_bag).exists():  # before --out is truncated or the bag read
        raise CommandError(f"{args.out_bag} exists already; choose a new --out-bag folder")
    if args.initial is not None and args.jobs != 1:
        raise CommandError(
            "--initial steers the first pair and tracking goes on from its result: use --jobs 1"
        )


def run(args: argparse.Namespace) -> int:
    settings = settings_from_args(args)
    check_arguments(args, settings)
    guess = guess_from_args(args, settings.dims)
    # Imported here: rosbags and tqdm are needed only when a bag is read.
    from frisicp_ros.bag.output import OutputError
    from frisicp_ros.bag.pairs import PairReading
    from frisicp_ros.bag.reader import BagError, open_bag, require_pointcloud2_topic
    from frisicp_ros.bag.run import Destinations, register_bag

    destinations = Destinations(args.out, args.out_bag, args.out_prefix, not args.no_progress, args.plot)
    try:
        with open_bag(args.input) as reader:
            for topic in (args.model_topic, args.data_topic):
                require_pointcloud2_topic(reader, topic)
            data_count = reader.topics[args.data_topic].msgcount
            reading = PairReading.paired_as(settings, reader, args.model_topic, args.data_topic)
            return register_bag(reading, settings, args.jobs, destinations, data_count, guess)
    except (BagError, OutputError) as err:
        raise CommandError(str(err)) from None
