"""``frisicp bag INPUT``: register the cloud pairs of a bag offline, without ROS.

Pairs are formed and registered by the same code as the live node (``pairing``, ``pipeline``,
``outputs``). Results go to JSONL (stdout by default) as they are computed and, with
``--out-bag``, into a rosbag2 with the node's output topics. Progress and the summary go to
stderr. Exit codes: 0 done, 1 the bag stopped being readable part-way (results so far kept),
2 bad arguments or an unreadable bag, 130 interrupted (results so far kept).
"""

from __future__ import annotations

import argparse
import signal
import statistics
import sys
import threading
import time
from collections.abc import Iterator
from concurrent.futures.process import BrokenProcessPool
from contextlib import closing
from dataclasses import dataclass, field, replace
from pathlib import Path

from tqdm import tqdm

from frisicp_core import Initialization, Method
from frisicp_ros.bag.jobs import ordered_map
from frisicp_ros.bag.output import JsonLines, OutputError, ResultBag, pair_record
from frisicp_ros.bag.pairs import BagPair, PairReading
from frisicp_ros.bag.reader import BagError, open_bag, require_pointcloud2_topic
from frisicp_ros.bag.registration import PairRegistrar
from frisicp_ros.cli.errors import CommandError
from frisicp_ros.stream.outputs import ALWAYS_PUBLISHED, build_outputs
from frisicp_ros.stream.pairing import PAIRING_MODES, Pairer
from frisicp_ros.stream.pipeline import PairOutcome, PipelineSettings

DEFAULTS = PipelineSettings()


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "bag",
        help="register the cloud pairs of a bag offline (no ROS installation needed)",
        description="Register every (model, data) PointCloud2 pair of a rosbag2 folder, .db3 or "
        ".mcap file, or ROS 1 .bag, paired as the live node pairs them. One JSON line "
        "per pair on stdout (or --out), a progress bar and a summary on stderr.",
    )
    parser.add_argument("input", help="rosbag2 folder, .db3 or .mcap file, or ROS 1 .bag file")
    parser.add_argument("--model-topic", required=True, help="PointCloud2 topic that stays fixed")
    parser.add_argument("--data-topic", required=True, help="PointCloud2 topic registered onto the model")
    parser.add_argument(
        "--pairing",
        choices=PAIRING_MODES,
        default=DEFAULTS.pairing,
        help="latest_model: each data cloud with the newest model before it; "
        "synchronized: model and data with header stamps within --sync-tolerance",
    )
    parser.add_argument(
        "--sync-tolerance",
        type=float,
        default=DEFAULTS.sync_tolerance,
        metavar="SEC",
        help="largest stamp difference of a synchronized pair (default %(default)s)",
    )
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
        "--no-aligned", action="store_true", help="leave the aligned data clouds out of the result bag"
    )
    parser.add_argument(
        "--jobs",
        type=int,
        default=1,
        metavar="N",
        help="registration processes; results stay in bag order (default 1)",
    )
    parser.add_argument(
        "--warm-start",
        action="store_true",
        help="start each pair from the previous estimate, as the node does (--jobs 1 only)",
    )
    parser.add_argument(
        "--dims", type=int, choices=(2, 3), default=DEFAULTS.dims, help="3: x y z; 2: x y only (planar scans)"
    )
    parser.add_argument(
        "--max-points",
        type=int,
        default=DEFAULTS.max_points,
        metavar="N",
        help="random down-sampling cap per cloud, 0 = none (default %(default)s)",
    )
    parser.add_argument("--method", choices=[m.value for m in Method], default=DEFAULTS.method)
    parser.add_argument(
        "--overlap",
        type=float,
        default=DEFAULTS.overlap,
        help="fraction of each cloud expected to have a counterpart (trimming); 1 = all",
    )
    parser.add_argument("--levels", type=int, default=DEFAULTS.levels, help="sparse-to-dense levels")
    parser.add_argument(
        "--init",
        choices=[i.value for i in Initialization],
        default=DEFAULTS.initialization,
        help="starting guess",
    )
    parser.add_argument("--model-frame", default="", help="expected model frame id (default: any)")
    parser.add_argument("--data-frame", default="", help="expected data frame id (default: any)")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    parser.set_defaults(func=run)


def settings_from_args(args: argparse.Namespace) -> PipelineSettings:
    try:
        return PipelineSettings(
            dims=args.dims,
            max_points=args.max_points,
            warm_start=args.warm_start,
            pairing=args.pairing,
            sync_tolerance=args.sync_tolerance,
            model_frame=args.model_frame,
            data_frame=args.data_frame,
            publish_aligned=not args.no_aligned,
            method=args.method,
            levels=args.levels,
            overlap=args.overlap,
            initialization=args.init,
        )
    except ValueError as err:
        raise CommandError(str(err)) from None


@dataclass
class RunStats:
    started: float = field(default_factory=time.perf_counter)
    pairs: int = 0
    rejected: int = 0
    converged: int = 0
    rms: list[float] = field(default_factory=list)
    register_seconds: float = 0.0
    last: str = "before the first pair"

    def add(self, pair: BagPair, outcome: PairOutcome) -> None:
        self.pairs += 1
        self.last = f"after pair {pair.index} (data cloud at bag time {pair.data.bag_ns} ns)"
        self.register_seconds += outcome.timings.register_seconds
        if outcome.result is None:
            self.rejected += 1
            return
        self.converged += outcome.result.converged
        self.rms.append(outcome.result.rms)

    def summary(self, unpaired: int) -> str:
        seconds = time.perf_counter() - self.started
        median = f"{statistics.median(self.rms):.6g}" if self.rms else "n/a"
        rate = f", {self.pairs / seconds:.2f} pairs/s" if seconds > 0 and self.pairs else ""
        text = (
            f"pairs {self.pairs} (rejected {self.rejected}), converged {self.converged}, "
            f"median RMS {median}, time {seconds:.2f} s{rate}"
        )
        if unpaired:
            text += f"; {unpaired} data clouds found no model"
        return text


class InterruptRequest:
    """Ctrl-C as a request: the pair in hand is finished and written to every output (so the
    JSONL and the result bag hold the same pairs), then the run stops. A second Ctrl-C stops at
    once. Only in the main thread, where Python delivers signals; elsewhere Ctrl-C is as usual.
    """

    def __init__(self) -> None:
        self.requested = False
        self._previous: object = None

    def __enter__(self) -> InterruptRequest:
        if threading.current_thread() is threading.main_thread():
            self._previous = signal.signal(signal.SIGINT, self._on_interrupt)
        return self

    def _on_interrupt(self, signum: int, frame: object) -> None:
        if self.requested:
            raise KeyboardInterrupt
        self.requested = True

    def __exit__(self, *exc_info: object) -> None:
        if self._previous is not None:
            signal.signal(signal.SIGINT, self._previous)


def check_arguments(args: argparse.Namespace, settings: PipelineSettings) -> None:
    if args.model_topic == args.data_topic:
        raise CommandError("--model-topic and --data-topic must be different topics")
    if args.jobs < 1:
        raise CommandError(f"--jobs must be >= 1, got {args.jobs}")
    if settings.warm_start and args.jobs > 1:
        raise CommandError("--warm-start chains every pair to the one before it: it needs --jobs 1")
    if args.out_bag and Path(args.out_bag).exists():  # before --out is truncated or the bag read
        raise CommandError(f"{args.out_bag} exists already; choose a new --out-bag folder")


def run(args: argparse.Namespace) -> int:
    settings = settings_from_args(args)
    check_arguments(args, settings)
    try:
        with open_bag(args.input) as reader:
            for topic in (args.model_topic, args.data_topic):
                require_pointcloud2_topic(reader, topic)
            data_count = reader.topics[args.data_topic].msgcount
            reading = PairReading(
                reader, args.model_topic, args.data_topic, Pairer(settings.pairing, settings.sync_tolerance)
            )
            return process_bag(args, settings, reading, data_count)
    except (BagError, OutputError) as err:
        raise CommandError(str(err)) from None


def process_bag(
    args: argparse.Namespace, settings: PipelineSettings, reading: PairReading, data_count: int
) -> int:
    topics = ALWAYS_PUBLISHED + (("aligned",) if settings.publish_aligned else ())
    results = JsonLines(args.out)
    result_bag = ResultBag(args.out_bag, args.out_prefix, topics) if args.out_bag else None
    stats = RunStats()
    progress = tqdm(
        total=data_count,
        unit="cloud",
        desc="registering",
        file=sys.stderr,
        disable=args.no_progress,
        dynamic_ncols=True,
    )
    stopped: str | None = None
    code = 0
    try:
        pairs: Iterator[BagPair] = iter(reading)
        # closing(): leaving the loop early must stop the workers right away.
        with (
            InterruptRequest() as interrupt,
            closing(ordered_map(PairRegistrar(settings), pairs, args.jobs)) as registered,
        ):
            for pair, outcome in registered:
                outcome = replace(outcome, data_msg=pair.data.cloud)
                results.write(pair_record(pair, outcome))
                if result_bag is not None and outcome.result is not None:
                    result_bag.write(pair.data.bag_ns, build_outputs(outcome, result_bag.types, topics))
                stats.add(pair, outcome)
                progress.update(pair.data.ordinal + 1 - progress.n)
                if interrupt.requested:
                    raise KeyboardInterrupt
        if reading.stopped is not None:
            stopped, code = reading.stopped, 1
        else:
            progress.update(data_count - progress.n)
    except KeyboardInterrupt:
        stopped, code = "interrupted", 130
    except BrokenProcessPool:
        stopped, code = "a worker process died (out of memory?)", 1
    except OutputError as err:  # a full disk, a closed pipe: what was written stays
        stopped, code = str(err), 1
    finally:
        progress.close()
        results.close()
    kept = f"{stats.pairs} results kept in {'stdout' if args.out == '-' else args.out}"
    if result_bag is not None:
        written = result_bag.close()
        kept += f" and {written}"
    if stopped is not None:
        print(f"frisicp bag: stopped {stats.last}: {stopped}; {kept}", file=sys.stderr)
    print(f"frisicp bag: {stats.summary(reading.pairer.unpaired_data)}", file=sys.stderr)
    if stats.pairs == 0 and stopped is None:
        print(f"frisicp bag: no pairs: {no_pairs_hint(args, reading)}", file=sys.stderr)
    return code


def no_pairs_hint(args: argparse.Namespace, reading: PairReading) -> str:
    if reading.model_clouds == 0 or reading.data_clouds == 0:
        return f"{reading.model_clouds} model and {reading.data_clouds} data clouds in the bag"
    if args.pairing == "latest_model":
        return "every data cloud came before the first model cloud"
    return (
        f"no model and data header stamps within --sync-tolerance {args.sync_tolerance} s "
        "(try a larger tolerance, or --pairing latest_model)"
    )
