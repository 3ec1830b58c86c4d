"""``frisicp bag INPUT [INPUT ...]``: register the cloud pairs of bags offline, without ROS.

Pairs are formed and registered by the same code as the live node (``pairing``, ``pipeline``,
``outputs``). Results go to JSONL (stdout by default) as they are computed and, with
``--out-bag``, into a rosbag2 with the node's output topics; several bags write one JSONL (and
with ``--result-bags`` one result bag) per bag into ``--out-dir``; ``--plot PNG`` (``--plots``
with ``--out-dir``) draws the results over time. ``--jobs N`` registers on this machine's
processes, ``--scheduler ADDRESS`` on a Dask cluster (``frisicp_ros.bag.cluster``); ``--initial``
steers each bag's first pair and needs one local job. Progress and the summaries go to stderr.
Exit codes: 0 every bag was read to its end (rejected or unreliable pairs are marked per line and
counted in the summary), 1 a bag was unreadable or stopped being readable part-way, or an output
(a picture included) or the executor failed (results so far kept), 2
bad arguments, an unreadable single bag or no readable bag at all, or an unreachable scheduler,
130 interrupted (Ctrl-C), 143 terminated (SIGTERM) (results so far kept in both).
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING

from frisicp_ros.cli.command import CommandError
from frisicp_ros.cli.options import add_guess_options, add_options, given_values, guess_from_args
from frisicp_ros.stream.settings import PipelineSettings, Surface, settings_from

if TYPE_CHECKING:
    from frisicp_core import InitialGuess
    from frisicp_ros.bag.executors import Executor
    from frisicp_ros.bag.run import BagJob

NAME = "bag"
MAX_JOBS = 256  # processes; more only exhausts memory (each holds its clouds and a KD-tree)
SUMMARY = "register the cloud pairs of bags offline (no ROS installation needed), here or on a Dask cluster"
DESCRIPTION = (
    "Register every (model, data) PointCloud2 pair of rosbag2 folders, .db3 or "
    ".mcap files, or ROS 1 .bag files, paired and registered as the live node does it, with the "
    "node's defaults. One JSON line per pair on stdout (or --out, or one file per bag in "
    "--out-dir), a progress bar and a summary on stderr."
)
RESULT_BAG_SUFFIX = "_results"  # --out-dir DIR --result-bags: DIR/<bag name>_results/
PICTURE_SUFFIX = ".png"  # --out-dir DIR --plots: DIR/<bag name>.png


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "inputs",
        nargs="+",
        metavar="INPUT",
        help="rosbag2 folder, .db3 or .mcap file, or ROS 1 .bag file; several need --out-dir",
    )
    parser.add_argument("--model-topic", required=True, help="PointCloud2 topic that stays fixed")
    parser.add_argument("--data-topic", required=True, help="PointCloud2 topic registered onto the model")
    parser.add_argument(
        "--out", default="-", metavar="FILE", help="JSONL result file, one line per pair (default: stdout)"
    )
    parser.add_argument(
        "--out-bag", metavar="DIR", help="also write a rosbag2 (mcap) with the node's output topics"
    )
    parser.add_argument(
        "--out-dir",
        metavar="DIR",
        help="one JSONL file per bag, DIR/<bag name>.jsonl (created if missing); needed for several bags",
    )
    parser.add_argument(
        "--result-bags",
        action="store_true",
        help=f"with --out-dir: also a result bag per bag, DIR/<bag name>{RESULT_BAG_SUFFIX}",
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
        default=None,
        metavar="N",
        help=f"registration processes on this machine, 1..{MAX_JOBS}; results stay in bag order. With"
        " warm start each worker warm-starts within chunks of consecutive pairs (default 1)",
    )
    parser.add_argument(
        "--scheduler",
        metavar="ADDRESS",
        help="register on the Dask cluster of this scheduler (tcp://host:8786, or a scheduler file);"
        " the bags must be at the same path on every worker (a shared filesystem)",
    )
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    parser.add_argument(
        "--plot",
        metavar="PNG",
        help="also draw scale, rotation, RMS, registration time and every pair's verdict over the bag's"
        " time into this PNG",
    )
    parser.add_argument(
        "--plots",
        action="store_true",
        help=f"with --out-dir: also that picture per bag, DIR/<bag name>{PICTURE_SUFFIX}",
    )
    add_guess_options(
        parser,
        "the first pair of each bag is registered around it instead of blind, and tracking follows"
        " (on this machine, one job)",
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
    if args.jobs is not None and not 1 <= args.jobs <= MAX_JOBS:
        raise CommandError(f"--jobs must be in [1, {MAX_JOBS}], got {args.jobs}")
    if args.jobs is not None and args.scheduler:
        raise CommandError("--jobs is for this machine; with --scheduler the cluster's workers run the pairs")
    if args.out_dir and (args.out != "-" or args.out_bag or args.plot):
        raise CommandError(
            "--out-dir writes one file per bag: leave out --out, --out-bag and --plot"
            " (--result-bags and --plots give a result bag and a picture per bag)"
        )
    if args.result_bags and not args.out_dir:
        raise CommandError("--result-bags applies only with --out-dir (one bag: --out-bag DIR)")
    if args.plots and not args.out_dir:
        raise CommandError("--plots applies only with --out-dir (one bag: --plot PNG)")
    if len(args.inputs) > 1 and not args.out_dir:
        raise CommandError(f"{len(args.inputs)} bags need --out-dir DIR (one JSONL file per bag)")
    if args.out_bag and Path(args.out_bag).exists():  # before --out is truncated or the bag read
        raise CommandError(f"{args.out_bag} exists already; choose a new --out-bag folder")
    if args.initial is not None and (args.scheduler or (args.jobs or 1) != 1):
        # Parallel chunks and cluster tasks start blind, exactly where the guess is needed.
        raise CommandError(
            "--initial steers each bag's first pair and tracking goes on from its result, pair after"
            " pair: leave out --jobs N and --scheduler"
        )


def bag_name(path: Path) -> str:
    """A bag's name in --out-dir: a rosbag2 folder's name, a file's name without its suffix."""
    resolved = path.resolve()
    return resolved.name if resolved.is_dir() else resolved.stem


def bag_jobs(args: argparse.Namespace) -> list[BagJob]:
    """Every input with its destinations; refuses clashing names and existing result bags."""
    from frisicp_ros.bag.run import BagJob, Destinations

    paths = [Path(p) for p in args.inputs]
    if not args.out_dir:
        return [BagJob(paths[0], Destinations(args.out, args.out_bag, args.out_prefix, args.plot))]
    out_dir = Path(args.out_dir)
    names: dict[str, Path] = {}
    for path in paths:
        name = bag_name(path)
        if name in names:
            raise CommandError(
                f"{names[name]} and {path} would both write {out_dir / name}.jsonl; "
                "give the bags distinct names (or run them in separate batches)"
            )
        names[name] = path
    jobs = []
    for name, path in names.items():
        result_bag = out_dir / f"{name}{RESULT_BAG_SUFFIX}" if args.result_bags else None
        if result_bag is not None and result_bag.exists():
            raise CommandError(f"{result_bag} exists already; choose a new --out-dir (or remove it)")
        to = Destinations(
            str(out_dir / f"{name}.jsonl"),
            str(result_bag) if result_bag else None,
            args.out_prefix,
            str(out_dir / f"{name}{PICTURE_SUFFIX}") if args.plots else None,
        )
        jobs.append(BagJob(path, to, name if len(paths) > 1 else ""))
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise CommandError(f"cannot create --out-dir {out_dir}: {err.strerror or err}") from None
    return jobs


def executor_for(args: argparse.Namespace, guess: InitialGuess | None) -> Executor:
    if not args.scheduler:
        from frisicp_ros.bag.executors import LocalProcesses

        return LocalProcesses(args.jobs or 1, guess)
    try:
        from frisicp_ros.bag.cluster import ClusterError, DaskCluster
    except ImportError as err:
        raise CommandError(
            f"--scheduler needs Dask's distributed package ({err}): pip install 'frisicp_ros[dask]'"
        ) from None
    try:
        return DaskCluster(args.scheduler)
    except ClusterError as err:
        raise CommandError(str(err)) from None


def run(args: argparse.Namespace) -> int:
    settings = settings_from_args(args)
    check_arguments(args, settings)
    guess = guess_from_args(args, settings.dims)
    # Imported here: rosbags and tqdm are needed only when a bag is read.
    from frisicp_ros.bag.output import OutputError
    from frisicp_ros.bag.run import BagRun, register_batch

    runs = [BagRun(job, settings, (args.model_topic, args.data_topic)) for job in bag_jobs(args)]
    for bag in runs:
        bag.survey()
    if len(runs) == 1 and runs[0].unreadable:  # one bag: its error is the command's
        raise CommandError(runs[0].unreadable)
    executor = executor_for(args, guess)
    try:
        return register_batch(runs, executor, progress=not args.no_progress)
    except OutputError as err:
        raise CommandError(str(err)) from None
