"""`make bench-smoke`: every script in benchmarks/ once with ``--quick``, ``--jobs`` at a time.

The smoke run only asks whether each script still runs against today's code (its figures come
from the full runs, in docs/), so the scripts need not run alone: two at a time take half the
wall time on a 2-core machine (CI's budget is 30 minutes; one at a time took 10 of them). Each
script's output goes to ``build/bench-smoke/<name>.log``; a line ``ok   <name> (<s> s)``, with
the script's own "skipped" lines, where it exits 0, else its whole log and ``FAIL <name>``. The
exit code is 1 when any failed (all of them run, so one run names every broken script).

The scripts known to take longest start first, so that the last ones to finish are short. Every
script that starts ROS has a domain of its own (node_latency 188, big_map_node 189,
doc_pictures 187), so two never meet on DDS.

    python tools/bench_smoke.py            # every script, two at a time
    python tools/bench_smoke.py --jobs 1   # one at a time
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor, as_completed
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
LOGS = ROOT / "build" / "bench-smoke"
# The longest with --quick on the 2-core VM, one at a time (2026-12-06: 120, 89, 59, 57, 53 and 44 s of
# 623 s in all): started first.
LONGEST_FIRST = (
    "cluster_throughput",
    "partial_overlap",
    "bag_throughput",
    "trustworthy",
    "doc_pictures",
    "noise_growth",
)


@dataclass(frozen=True)
class Outcome:
    name: str
    code: int
    seconds: float
    log: Path


def scripts(folder: Path) -> list[Path]:
    """The benchmark scripts, the known long ones first, then the rest by name."""
    found = sorted(folder.glob("*.py"))
    rank = {name: k for k, name in enumerate(LONGEST_FIRST)}
    return sorted(found, key=lambda path: (rank.get(path.stem, len(rank)), path.stem))


def run(script: Path, logs: Path) -> Outcome:
    """``script --quick`` on one OpenMP thread, its output into its log in ``logs``."""
    log = logs / f"{script.stem}.log"
    env = dict(os.environ, OMP_NUM_THREADS="1")
    start = time.monotonic()
    with log.open("w") as out:
        code = subprocess.run(
            [sys.executable, str(script), "--quick"], stdout=out, stderr=subprocess.STDOUT, env=env, cwd=ROOT
        ).returncode
    return Outcome(script.stem, code, time.monotonic() - start, log)


def report(outcome: Outcome) -> None:
    text = outcome.log.read_text(errors="replace")
    if outcome.code == 0:
        print(f"ok   {outcome.name} ({outcome.seconds:.0f} s)")
        for line in text.splitlines():
            if "skipped" in line:
                print(line)
    else:
        print(text, end="" if text.endswith("\n") else "\n")
        print(f"FAIL {outcome.name} (exit {outcome.code}; whole output above, and in {outcome.log})")
    sys.stdout.flush()


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--jobs", type=int, default=2, help="scripts at a time (default 2)")
    parser.add_argument(
        "--scripts", type=Path, default=ROOT / "benchmarks", help="their folder (default benchmarks/)"
    )
    parser.add_argument(
        "--logs", type=Path, default=LOGS, help="where the logs go (default build/bench-smoke/)"
    )
    args = parser.parse_args(argv)
    if args.jobs < 1:
        parser.error("--jobs must be at least 1")
    args.logs.mkdir(parents=True, exist_ok=True)
    start = time.monotonic()
    failed = []
    with ThreadPoolExecutor(max_workers=args.jobs) as pool:
        # Reported as each finishes: a broken script shows up at once, not after the others.
        futures = [pool.submit(run, script, args.logs) for script in scripts(args.scripts)]
        for future in as_completed(futures):
            outcome = future.result()
            report(outcome)
            if outcome.code != 0:
                failed.append(outcome.name)
    print(f"bench-smoke: {len(futures)} scripts, {args.jobs} at a time, {time.monotonic() - start:.0f} s")
    if failed:
        print(f"bench-smoke FAILED: {', '.join(failed)}")
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
