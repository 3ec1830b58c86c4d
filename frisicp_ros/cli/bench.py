"""``frisicp bench``: the paper's experiments on ../shared/data, written to docs/benchmarks/."""

from __future__ import annotations

import argparse
import dataclasses
import datetime
import os
import platform
import time
from pathlib import Path

import numpy as np
import scipy

from frisicp_ros.cli.errors import CommandError


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "bench",
        help="run the paper's experiments on the real data; write tables, JSON and figures",
        description="FRISICP against ICP, Zinßer's and Du's scale ICP (and Open3D when installed) "
        "over the paper's 15 scale factors on MPEG-7 contours and the Stanford bunny.",
    )
    parser.add_argument(
        "--quick",
        action="store_true",
        help="a small subset (3 scales, apple and the low-resolution bunny) for CI",
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
        help="the shared data folder (default: $FRISICP_DATA, else ../shared/data from the current directory)",
    )
    parser.add_argument("--seed", type=int, default=0, help="seed of the perturbations")
    parser.add_argument("--no-open3d", action="store_true", help="leave Open3D out even when installed")
    parser.add_argument("--no-figures", action="store_true", help="tables and JSON only")
    parser.set_defaults(func=run)


def environment(open3d_used: bool) -> dict[str, str]:
    versions = {
        "date": datetime.date.today().isoformat(),
        "machine": f"{platform.machine()} {os.cpu_count()} CPUs",
        "OMP_NUM_THREADS": os.environ.get("OMP_NUM_THREADS", "unset"),
        "python": platform.python_version(),
        "numpy": np.__version__,
        "scipy": scipy.__version__,
    }
    if open3d_used:
        import open3d

        versions["open3d"] = open3d.__version__
    else:
        versions["open3d"] = "not used"
    return versions


def run(args: argparse.Namespace) -> int:
    # Imported here: `frisicp --help` and the other subcommands need no benchmark modules.
    from frisicp_bench.datasets import DataMissingError, default_data_dir
    from frisicp_bench.methods import paper_methods
    from frisicp_bench.runner import run_benchmark
    from frisicp_bench.suites import full_suite, quick_suite
    from frisicp_bench.tables import write_tables
    from frisicp_bench.targets import check_targets

    data_dir = args.data or default_data_dir()
    out_dir = args.out or Path("build/bench-quick" if args.quick else "docs/benchmarks")
    suite = quick_suite() if args.quick else full_suite()
    methods = [m for m in paper_methods() if not (args.no_open3d and m.key == "open3d")]
    start = time.perf_counter()
    try:
        families = suite.families(data_dir)
    except DataMissingError as err:
        raise CommandError(str(err)) from None
    print(
        f"{suite.name} run: {len(families)} families x {len(suite.scales)} scales, "
        f"methods {', '.join(m.key for m in methods)}",
        flush=True,
    )
    result = run_benchmark(
        families, methods, suite.scales, args.seed, progress=lambda line: print(line, flush=True)
    )
    figures: list[str] = []
    if not args.no_figures:
        from frisicp_bench.figures import write_figures

        figures = [path.name for path in write_figures(result, out_dir)]
    # The duration covers loading, all registrations and the figures.
    result = dataclasses.replace(result, seconds=time.perf_counter() - start)
    checks = check_targets(result)
    written = write_tables(
        result,
        checks,
        environment(any(m.key == "open3d" for m in methods)),
        figures,
        out_dir,
        command_line(args),
    )
    for check in checks:
        print(f"[{'met' if check.met else 'MISSED'}] {check.target}: {check.detail}")
    print(
        f"{result.seconds / 60:.1f} min; wrote {', '.join(str(p) for p in written)} and {len(figures)} figures"
    )
    return 0


def command_line(args: argparse.Namespace) -> str:
    """The command that reproduces a run, for the report's header."""
    words = ["frisicp", "bench"]
    if args.quick:
        words.append("--quick")
    if args.seed != 0:
        words += ["--seed", str(args.seed)]
    if args.no_open3d:
        words.append("--no-open3d")
    return " ".join(words)
