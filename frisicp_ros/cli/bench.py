"""``frisicp bench``: the paper's experiments (``frisicp_bench``) on the real data."""

from __future__ import annotations

import argparse
from pathlib import Path

from frisicp_ros.cli.command import CommandError

NAME = "bench"
SUMMARY = "run the paper's experiments on the real data; write tables, JSON and figures"
DESCRIPTION = (
    "FRISICP against ICP, Zinßer's and Du's scale ICP (and Open3D when installed) "
    "over the paper's 15 scale factors on MPEG-7 contours, the Stanford bunny, a pair of its scans "
    "and four scans in the bunny as their map."
)


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--quick",
        action="store_true",
        help="a small subset for CI (3 scales; apple, the low-resolution bunny and one scan in it)",
    )
    parser.add_argument(
        "--out",
        type=Path,
        default=None,
        help="output folder (default: docs/benchmarks, or build/bench-quick with --quick)",
    )
    parser.add_argument(
        "--data",
        type=Path,
        default=None,
        help="the shared data folder (default: $FRISICP_DATA, else ../shared/data beside the repository)",
    )
    parser.add_argument("--seed", type=int, default=0, help="seed of the perturbations")
    parser.add_argument("--no-open3d", action="store_true", help="leave Open3D out even when installed")
    parser.add_argument("--no-figures", action="store_true", help="tables and JSON only")


def run(args: argparse.Namespace) -> int:
    # Imported here: `frisicp --help` and the other subcommands need no benchmark modules.
    from frisicp_bench.datasets import DataMissingError
    from frisicp_bench.run import BenchOptions
    from frisicp_bench.run import run as run_benchmark

    options = BenchOptions(
        args.quick, args.out, args.data, args.seed, not args.no_open3d, not args.no_figures
    )
    try:
        run_benchmark(options)
    except DataMissingError as err:
        raise CommandError(str(err)) from None
    return 0
