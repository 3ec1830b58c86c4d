"""What the stand-alone scripts in ``benchmarks/`` share: their command line, where they read the
data and write their reports, and how they skip what this machine lacks.

Every script takes ``--quick``: each of its sections once, on a small subset, in seconds, with
the report under ``build/`` so that ``docs/`` keeps the figures of full runs. ``make
bench-smoke`` runs them all (CI does), so a script that no longer runs against today's code
fails there instead of in the next person's measurement. A script that needs the real data takes
``--data`` (default :func:`.datasets.default_data_dir`) and exits 0 without measuring, saying
so, when the data is absent; one that needs an optional package (ROS, Open3D) skips that part
likewise.
"""

from __future__ import annotations

import argparse
import json
import shlex
import sys
from collections.abc import Callable, Iterable, Sequence
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any, TypeVar

from .datasets import DataMissingError, default_data_dir

T = TypeVar("T")
S = TypeVar("S")

# The scales of a smoke run: the extremes of the paper's 15.
SMOKE_SCALES = (0.1, 2.9)


def parser(
    script: str,
    doc: str | None,
    quick: str,
    *,
    data: bool = False,
    seed: bool = False,
    report: bool = False,
    repeats: int | None = None,
    json_out: bool = False,
) -> argparse.ArgumentParser:
    """The command line of ``script`` (its ``__file__``): described by the first line of its
    docstring ``doc``, with ``--quick`` (``quick`` says what the smoke run does) and the shared
    options asked for: ``--data``, ``--seed``, ``--out`` (a Markdown report, JSON beside it),
    ``--repeats`` (with this default) and ``--json`` (the figures as JSON)."""
    path = Path(script).resolve()
    command = argparse.ArgumentParser(
        prog=f"python benchmarks/{path.name}", description=(doc or path.stem).strip().splitlines()[0]
    )
    command.set_defaults(script=path)
    command.add_argument(
        "--quick", action="store_true", help="a smoke run of seconds: " + quick.replace("%", "%%")
    )
    if data:
        command.add_argument(
            "--data",
            type=Path,
            default=default_data_dir(),
            metavar="DIR",
            help="the shared data folder (default: $FRISICP_DATA, else ../shared/data beside the repository)",
        )
    if seed:
        command.add_argument("--seed", type=int, default=0, help="seed of the perturbations (default 0)")
    if report:
        command.set_defaults(report_out=True)
        command.add_argument(
            "--out",
            type=Path,
            default=None,
            metavar="FILE.md",
            help=f"the Markdown report, its JSON beside it (default docs/{path.stem}.md; "
            f"build/{path.stem}.md with --quick)",
        )
    if repeats is not None:
        command.add_argument(
            "--repeats", type=int, default=repeats, help=f"timed runs per case (default {repeats})"
        )
    if json_out:
        command.add_argument(
            "--json", type=Path, default=None, metavar="FILE", help="also write the figures here (JSON)"
        )
    return command


def parse(command: argparse.ArgumentParser, argv: Sequence[str] | None = None) -> argparse.Namespace:
    """The arguments, with ``argv`` (the words after the script) kept for :func:`command_line`
    and ``--out`` resolved: docs/NAME.md, or build/NAME.md for a ``--quick`` run."""
    words = list(sys.argv[1:] if argv is None else argv)
    args = command.parse_args(words)
    args.argv = words
    if getattr(args, "report_out", False) and args.out is None:
        args.out = report_path(args.script, args.quick)
    return args


def report_path(script: Path, quick: bool) -> Path:
    """Where ``script`` writes its report: the repository's docs/, or build/ for a smoke run."""
    return script.parents[1] / ("build" if quick else "docs") / f"{script.stem}.md"


def command_line(args: argparse.Namespace) -> str:
    """The command that produced a report, as run from the repository root."""
    return shlex.join(["python", f"benchmarks/{args.script.name}", *args.argv])


def skip(args: argparse.Namespace, reason: str) -> int:
    """Say on stderr why ``args.script`` measures nothing (or less) here; the exit code 0."""
    print(f"{args.script.stem}: skipped, {reason}", file=sys.stderr)
    return 0


def load_data(args: argparse.Namespace, load: Callable[[Path], T]) -> T | None:
    """``load(args.data)``, or None after saying which data file is missing (:func:`skip`)."""
    try:
        return load(args.data)
    except DataMissingError as err:
        skip(args, f"no data: {err}")
        return None


def map_cases(
    args: argparse.Namespace, work: Callable[[S], T], cases: Iterable[S], line: Callable[[T], str]
) -> list[T] | None:
    """``work`` on every case in ``args.jobs`` worker processes (``work`` must pickle: a module
    function, or one bound by ``functools.partial``), the results in the cases' order, each
    result's ``line`` on stderr as it comes; or None after saying which data file is missing
    (:func:`skip`)."""
    results: list[T] = []
    try:
        with ProcessPoolExecutor(max_workers=max(1, args.jobs)) as pool:
            for result in pool.map(work, cases):
                results.append(result)
                print(line(result), file=sys.stderr, flush=True)
    except DataMissingError as err:
        skip(args, f"no data: {err}")
        return None
    return results


def write_json(path: Path | None, document: Any) -> None:
    """Write ``document`` as indented JSON to ``path`` (``--json``), if one was given."""
    if path is not None:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps(document, indent=1) + "\n")
