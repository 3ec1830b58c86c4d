"""The fault campaign (``make fuzz``): hostile input to every entry point, bounded in count and time.

Parts (``--only`` picks some): ``files`` (hostile files to ``frisicp register``), ``bags``
(damaged bags to ``frisicp bag``), ``signals`` (SIGINT/SIGTERM storms to ``frisicp bag --jobs
1|2``), ``node`` (hostile PointCloud2 messages and parameter attacks to a running
``register_node``, over DDS on loopback only, in ROS domain 171). Everything runs niced, seeded
(``--seed``), with temporary files under ``build/fuzz``. Each part stops at its count or its
share of ``--minutes``, whichever comes first; the summary says how many were tried.

Prints one line per part and a Markdown table for docs/reliability.md; exits 1 if anything
crashed, printed a traceback, hung, lost results, published a wrong answer, ignored a signal or
gave an unclear error.
"""

from __future__ import annotations

import argparse
import platform
import shutil
import sys
import time
from datetime import date
from pathlib import Path

import numpy as np
from common import Tally, niced

ROOT = Path(__file__).resolve().parents[2]
PARTS = ("files", "bags", "signals", "node")
# Each part's share of the time and its count at the default size (--scale multiplies counts).
SHARE = {"files": 0.15, "bags": 0.25, "signals": 0.2, "node": 0.4}
COUNT = {"files": 3, "bags": 60, "signals": 12, "node": 2000, "attacks": 400}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--minutes", type=float, default=10.0, help="bound on the whole run (default 10)")
    parser.add_argument("--scale", type=float, default=1.0, help="multiplies every part's count (default 1)")
    parser.add_argument("--seed", type=int, default=17)
    parser.add_argument("--only", nargs="+", choices=PARTS, default=list(PARTS))
    args = parser.parse_args()
    niced()
    work = ROOT / "build" / "fuzz"
    shutil.rmtree(work, ignore_errors=True)
    work.mkdir(parents=True)
    rng = np.random.default_rng(args.seed)
    started = time.monotonic()
    budget = args.minutes * 60.0
    share = sum(SHARE[part] for part in args.only)
    tallies: list[Tally] = []
    for part in args.only:
        deadline = time.monotonic() + budget * SHARE[part] / share
        count = {name: max(1, round(value * args.scale)) for name, value in COUNT.items()}
        print(
            f"fuzz: {part} (until {time.monotonic() - started + budget * SHARE[part] / share:.0f} s)",
            flush=True,
        )
        if part == "files":
            import files

            tallies.append(files.campaign(work / "files", rng, count["files"], deadline))
        elif part == "bags":
            import bags

            tallies.append(bags.damaged_bags(work / "bags", rng, count["bags"], deadline))
        elif part == "signals":
            import bags

            tallies.append(bags.signal_storms(work / "signals", rng, count["signals"], deadline))
        else:
            import node

            tallies.extend(node.campaign(rng, count["node"], count["attacks"], deadline))
        for tally in tallies[-2 if part == "node" else -1 :]:
            print(tally.line(), flush=True)
    seconds = time.monotonic() - started
    print(report(tallies, seconds))
    for tally in tallies:
        for problem in tally.problems:
            print(f"  {tally.part}: {problem}")
    return 1 if any(tally.failures for tally in tallies) else 0


def report(tallies: list[Tally], seconds: float) -> str:
    machine = f"{platform.machine()}, {_cpus()} CPUs, Python {platform.python_version()}"
    lines = [
        "",
        f"Run of `make fuzz` on {date.today().isoformat()} ({machine}), {seconds / 60:.1f} min:",
        "",
        "| part | tried | crashes | tracebacks | hangs | lost results | wrong answers | ignored signals"
        " | unclear errors |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for t in tallies:
        lines.append(
            f"| {t.part} | {t.tried} | {t.crashes} | {t.tracebacks} | {t.hangs} | {t.lost_results}"
            f" | {t.wrong_answers} | {t.ignored_signals} | {t.unclear_errors} |"
        )
    return "\n".join(lines)


def _cpus() -> int:
    import os

    return len(os.sched_getaffinity(0))


if __name__ == "__main__":
    sys.exit(main())
