"""One run of the paper benchmark: load the suite, register every case, write the report.

``frisicp bench`` (``frisicp_ros.cli.bench``) parses the command line into :class:`BenchOptions`
and calls :func:`run`; nothing here knows about argparse or ROS.
"""

from __future__ import annotations

import dataclasses
import datetime
import os
import platform
import time
from pathlib import Path

import numpy as np
import scipy

from frisicp_bench.datasets import default_data_dir
from frisicp_bench.methods import paper_methods
from frisicp_bench.runner import run_benchmark
from frisicp_bench.suites import full_suite, quick_suite
from frisicp_bench.tables import write_tables
from frisicp_bench.targets import TargetCheck, check_targets


@dataclasses.dataclass(frozen=True)
class BenchOptions:
    quick: bool = False  # the CI subset
    out: Path | None = None  # default: docs/benchmarks, or build/bench-quick when quick
    data: Path | None = None  # default: datasets.default_data_dir()
    seed: int = 0
    open3d: bool = True  # compare with Open3D when it is installed
    figures: bool = True

    def command_line(self) -> str:
        """The command that reproduces a run, for the report's header."""
        words = ["frisicp", "bench"]
        if self.quick:
            words.append("--quick")
        if self.seed != 0:
            words += ["--seed", str(self.seed)]
        if not self.open3d:
            words.append("--no-open3d")
        return " ".join(words)


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


def run(options: BenchOptions) -> list[TargetCheck]:
    """Run the suite and write tables, JSON and figures; progress goes to stdout.

    Raises ``datasets.DataMissingError`` (naming the file) when the data is absent.
    """
    data_dir = options.data or default_data_dir()
    out_dir = options.out or Path("build/bench-quick" if options.quick else "docs/benchmarks")
    suite = quick_suite() if options.quick else full_suite()
    methods = [m for m in paper_methods() if options.open3d or m.key != "open3d"]
    start = time.perf_counter()
    families = suite.families(data_dir)
    print(
        f"{suite.name} run: {len(families)} families x {len(suite.scales)} scales, "
        f"methods {', '.join(m.key for m in methods)}",
        flush=True,
    )
    result = run_benchmark(
        families, methods, suite.scales, options.seed, progress=lambda line: print(line, flush=True)
    )
    figures: list[str] = []
    if options.figures:
        from frisicp_bench.figures import write_figures  # matplotlib: only when drawing

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
        options.command_line(),
    )
    for check in checks:
        print(f"[{'met' if check.met else 'MISSED'}] {check.target}: {check.detail}")
    print(
        f"{result.seconds / 60:.1f} min; wrote {', '.join(str(p) for p in written)} and {len(figures)} figures"
    )
    return checks
