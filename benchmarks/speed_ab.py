"""Speed of ``register`` at two revisions of frisicp_core, on `make bench`'s full-overlap cases, interleaved.

On a shared machine two timing runs an hour apart cannot tell a 20 % regression from a busier
machine. This script times both revisions in one session, alternating case by case: it extracts
frisicp_core at each revision (``git archive``; the working tree for ``--after`` by default),
starts one worker process per revision (each imports only its own frisicp_core), and sends
both the same cases of ``benchmarks/core_speed.py`` — the bunny reconstruction (35,947 points)
against a copy scaled by each of the 15 scales, rotated 10 deg and shifted — timing
``register(data, model)`` with each revision's default ``RegistrationConfig()``, repeat after
repeat. Load then slows both alike; the ratio of the medians is the measurement.

Usage::

    python benchmarks/speed_ab.py 7e9cfcc^            # before the partial-overlap core vs the working tree
    python benchmarks/speed_ab.py A --after B --threads 0 --repeats 7 --out docs/speed_ab.md
    python benchmarks/speed_ab.py 67ac26e^ --warm     # before issue 14, warm starts (tracking)
    python benchmarks/speed_ab.py 82b55a7^ --crops    # cold crops of real scenes (global search)
    python benchmarks/speed_ab.py aad415b^ --crops --reverse   # the scenes onto their crops
    python benchmarks/speed_ab.py 47b4fff^ --rooms    # furnished rooms and their 30 % crops, both ways
    python benchmarks/speed_ab.py --quick             # HEAD vs the working tree, 2 scales and a crop, once -> build/

``--crops`` times partial-overlap cold registrations instead, the cases that run the global
search: ``benchmarks/trustworthy.py``'s "crop onto scene" cases of 30-60 % crops at the node's
10,000-point cap, the first (index order) of each share on each of its scenes (12 cases; the
crops are built by today's code and handed to both workers as arrays, with the truth).
``--reverse`` takes its "scene onto crop" cases instead (the whole scene onto a 30-60 % crop of
it, chosen alike), where the search matches the scene's shapes onto the crop's and the search
with the clouds' roles swapped has its say more often.

``--rooms`` times ``benchmarks/structured_scenes.py --kinds furnished``'s 30 % cases of draw 0
instead (six synthetic furnished rooms onto a 30 % crop of each and six crops onto their rooms,
capped at 10,000 points): man-made scenes of boxes, where the plane-arrangement starts
(:mod:`frisicp_core.plane_arrangement`) join the search.

``--threads 1`` (default) sets OMP_NUM_THREADS=1 in both workers, as ``make bench-paper`` does;
0 leaves OpenMP's default. Exits 0 without measuring when the bunny (in ``--data``) is absent or
the repository is not a git checkout, saying so.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import subprocess
import sys
import tarfile
import tempfile
import time
from datetime import date
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
WORKTREE = "worktree"
WORKER = "--worker"  # argv[1] of a worker process, argv[2] the bunny's points (.npy)


def worker(points: str) -> int:
    """Serve timing requests on stdin, one JSON line each: {"scale": s, "warm": bool} -> seconds
    and accuracy. Warm: started where core_speed's warm start puts it (2 deg / 2 % off the truth,
    the same start in both workers: its generator is seeded by the scale).

    Imports only its revision's frisicp_core and core_speed's case (not frisicp_bench, which
    needs today's core). The points come read, as a .npy file: an older core may have no reader."""
    from core_speed import forward_similarity, warm_start

    import frisicp_core
    from frisicp_core import RegistrationConfig, register, rotation_angle

    model = np.load(points)
    print(json.dumps({"core": str(Path(frisicp_core.__file__).parent)}), flush=True)
    for line in sys.stdin:
        request = json.loads(line)
        config = RegistrationConfig()
        if "case" in request:  # a crop case (--crops): data, model and the truth as a matrix
            case = np.load(request["case"])
            data, case_model = case["data"], case["model"]
            truth = frisicp_core.Similarity.from_matrix(case["truth"])
        else:
            scale = request["scale"]
            forward = forward_similarity(scale)
            data, case_model = forward.apply(model), model
            truth = forward.inverse()
            if request.get("warm"):
                start_pose = warm_start(truth, np.random.default_rng(round(10 * scale)))
                config = RegistrationConfig(initial=start_pose)
        start = time.perf_counter()
        result = register(data, case_model, config)
        seconds = time.perf_counter() - start
        rotation = float(np.degrees(rotation_angle(result.similarity.rotation @ truth.rotation.T)))
        scale_error = abs(result.similarity.scale / truth.scale - 1.0)
        print(
            json.dumps({"seconds": seconds, "rotation_deg": rotation, "scale_error": scale_error}), flush=True
        )
    return 0


class Worker:
    """One revision's frisicp_core in its own process."""

    def __init__(self, label: str, core_parent: Path, threads: int, points: Path) -> None:
        env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(core_parent), str(ROOT / "benchmarks")]))
        if threads:
            env["OMP_NUM_THREADS"] = str(threads)
        else:
            env.pop("OMP_NUM_THREADS", None)
        self.label = label
        self.process = subprocess.Popen(
            [sys.executable, str(Path(__file__).resolve()), WORKER, str(points)],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            text=True,
            env=env,
            cwd=tempfile.gettempdir(),  # not the repository: its frisicp_core must not shadow PYTHONPATH's
        )
        self.core = self._read()["core"]
        if Path(self.core).parent.resolve() != core_parent.resolve():
            raise RuntimeError(f"{label}: imported {self.core}, not the revision's copy in {core_parent}")

    def time(self, case: float | Path, warm: bool = False) -> dict[str, float]:
        """One registration: a bunny case by its scale, or a crop case by its file (``--crops``,
        always cold)."""
        assert self.process.stdin is not None
        request = {"case": str(case)} if isinstance(case, Path) else {"scale": case, "warm": warm}
        self.process.stdin.write(json.dumps(request) + "\n")
        self.process.stdin.flush()
        return self._read()

    def _read(self) -> dict:
        assert self.process.stdout is not None
        line = self.process.stdout.readline()
        if not line:
            raise RuntimeError(f"worker {self.label} exited (code {self.process.wait()})")
        return json.loads(line)

    def close(self) -> None:
        assert self.process.stdin is not None
        self.process.stdin.close()
        self.process.wait()


def points_file(cloud: Path, folder: Path) -> Path:
    """``cloud`` read by today's core into a .npy file in ``folder``, for the workers."""
    from frisicp_core import read_points

    path = folder / f"{cloud.stem}.npy"
    np.save(path, read_points(cloud))
    return path


def crop_files(data_dir: Path, folder: Path, quick: bool, suite: str = "crop onto scene") -> dict[str, Path]:
    """``--crops``' cases (module doc) of ``suite`` built by today's code, one .npz file each
    (data, model, truth matrix), by case name."""
    import trustworthy

    files: dict[str, Path] = {}
    taken: set[tuple[str, float]] = set()
    for spec in trustworthy.specs(quick=False):
        share = spec.crop_share
        if spec.suite != suite or spec.cap != trustworthy.CAP or share is None or share < 0.3:
            continue
        if (spec.scene, share) in taken or (quick and files):
            continue
        taken.add((spec.scene, share))
        case, data, model, _ = trustworthy.capped_case(spec, data_dir)
        assert case.truth is not None
        path = folder / f"crop{len(files)}.npz"
        np.savez(path, data=data, model=model, truth=case.truth.matrix())
        files[case.name] = path
    return files


def room_files(folder: Path, quick: bool) -> dict[str, Path]:
    """``--rooms``' cases (module doc) built by today's code, one .npz file each (data, model,
    truth matrix), by case name and direction."""
    from frisicp_bench.structures import DIRECTIONS, seeded_case

    files: dict[str, Path] = {}
    for direction in DIRECTIONS:
        for repeat in range(1 if quick else 6):
            case, data, model = seeded_case("furnished", 0.3, direction, repeat, draw=0, cap=10_000)
            assert case.truth is not None
            path = folder / f"room{len(files)}.npz"
            np.savez(path, data=data, model=model, truth=case.truth.matrix())
            files[f"{case.name} {direction} #{repeat}"] = path
    return files


def extract_core(revision: str, into: Path) -> tuple[Path, str]:
    """frisicp_core at ``revision`` under ``into``/<name>/ (the working tree's own folder for WORKTREE),
    and which commit last changed it there."""
    if revision == WORKTREE:
        return ROOT, describe("HEAD") + ("-dirty" if dirty() else "")
    target = into / revision.replace("/", "_").replace("^", "_parent").replace("~", "_back")
    target.mkdir()
    archive = subprocess.run(
        ["git", "-C", str(ROOT), "archive", "--format=tar", revision, "frisicp_core"],
        capture_output=True,
        check=True,
    ).stdout
    archive_path = target / "core.tar"
    archive_path.write_bytes(archive)
    with tarfile.open(archive_path) as tar:
        tar.extractall(target, filter="data")
    return target, describe(revision)


def describe(revision: str) -> str:
    """The last commit that changed frisicp_core at ``revision``: ``hash (date): subject``, cut short."""
    line = subprocess.run(
        [
            "git",
            "-C",
            str(ROOT),
            "log",
            "-1",
            "--format=%h (%ad): %s",
            "--date=short",
            revision,
            "--",
            "frisicp_core",
        ],
        capture_output=True,
        text=True,
        check=True,
    ).stdout.strip()
    return line if len(line) <= 90 else line[:89] + "…"


def dirty() -> bool:
    status = subprocess.run(
        ["git", "-C", str(ROOT), "status", "--porcelain", "frisicp_core"], capture_output=True, text=True
    )
    return bool(status.stdout.strip())


def main(argv: list[str] | None = None) -> int:
    from core_speed import BUNNY, SCALES

    from frisicp_bench import script

    quick = "HEAD against the working tree, 2 scales and one crop (--crops: one crop), once"
    parser = script.parser(__file__, __doc__, quick, data=True, report=True, repeats=5)
    parser.add_argument("before", nargs="?", help="git revision of the reference core, e.g. 7e9cfcc^")
    parser.add_argument(
        "--after", default=WORKTREE, help="git revision to compare (default: the working tree)"
    )
    parser.add_argument("--threads", type=int, default=1, help="OMP_NUM_THREADS of the workers; 0: unset")
    parser.add_argument(
        "--warm", action="store_true", help="start 2 deg / 2 %% off the truth (core_speed's warm start)"
    )
    parser.add_argument(
        "--crops", action="store_true", help="cold 30-60 %% crops of real scenes (trustworthy.py's cases)"
    )
    parser.add_argument(
        "--reverse", action="store_true", help="with --crops: the scenes onto their crops instead"
    )
    parser.add_argument(
        "--rooms",
        action="store_true",
        help="furnished rooms and their 30 %% crops, both ways (structured_scenes.py's)",
    )
    args = script.parse(parser, argv)
    if args.rooms and (args.crops or args.warm):
        parser.error("--rooms times cold registrations of its own cases: no --crops, no --warm")
    if args.reverse and not args.crops:
        parser.error("--reverse goes with --crops")
    if args.quick:
        args.before, args.repeats = args.before or "HEAD", 1
    if args.before is None:
        parser.error("the reference revision is required")
    if args.crops and args.warm:
        parser.error("--crops times cold registrations: no --warm")
    scales = script.SMOKE_SCALES if args.quick else SCALES
    bunny = args.data / BUNNY
    if not bunny.exists():
        return script.skip(args, f"no data: {bunny} is absent")
    if not (ROOT / ".git").exists():
        return script.skip(args, f"{ROOT} is not a git checkout: no revisions to compare")
    load_start = os.getloadavg()[0]
    with tempfile.TemporaryDirectory() as folder:
        cores = {
            label: extract_core(rev, Path(folder))
            for label, rev in (("before", args.before), ("after", args.after))
        }
        points = points_file(bunny, Path(folder))
        cases: dict[str, float | Path] = {f"{scale:.1f}": scale for scale in scales}
        if args.crops:
            suite = "scene onto crop" if args.reverse else "crop onto scene"
            cases = dict(crop_files(args.data, Path(folder), args.quick, suite))
        elif args.rooms:
            cases = dict(room_files(Path(folder), args.quick))
        elif args.quick and (args.data / "real").is_dir():  # the smoke run takes both paths
            cases.update(crop_files(args.data, Path(folder), quick=True))
        workers = {label: Worker(label, parent, args.threads, points) for label, (parent, _) in cores.items()}
        try:
            for w in workers.values():
                w.time(next(iter(cases.values())), args.warm)  # warm-up: imports, first trees
            samples: dict[str, dict[str, list[dict[str, float]]]] = {
                label: {name: [] for name in cases} for label in workers
            }
            order = list(workers)
            for repeat in range(args.repeats):
                for k, (name, case) in enumerate(cases.items()):
                    # Alternate who goes first, so neither always follows the other's cache footprint.
                    for label in order if (repeat + k) % 2 == 0 else order[::-1]:
                        samples[label][name].append(workers[label].time(case, args.warm))
                print(f"repeat {repeat + 1}/{args.repeats} done", flush=True)
        finally:
            for w in workers.values():
                w.close()
    rows = []
    for name in cases:
        row: dict[str, Any] = {"case": name}
        for label in workers:
            runs = samples[label][name]
            row[f"{label}_ms"] = 1e3 * statistics.median(r["seconds"] for r in runs)
            row[f"{label}_rotation_deg"] = max(r["rotation_deg"] for r in runs)
            row[f"{label}_scale_error"] = max(r["scale_error"] for r in runs)
        row["ratio"] = row["after_ms"] / row["before_ms"]
        rows.append(row)
    total = {label: sum(r[f"{label}_ms"] for r in rows) for label in workers}
    summary = {
        "median_ratio": statistics.median(r["ratio"] for r in rows),
        "worst_ratio": max(r["ratio"] for r in rows),
        "total_ratio": total["after"] / total["before"],
        "median_before_ms": statistics.median(r["before_ms"] for r in rows),
        "median_after_ms": statistics.median(r["after_ms"] for r in rows),
        "load_average_start": load_start,
        "load_average_end": os.getloadavg()[0],
    }
    for r in rows:
        print(
            f"{r['case']:<36} before {r['before_ms']:7.1f} ms  after {r['after_ms']:7.1f} ms  ratio {r['ratio']:.2f}"
        )
    print(
        f"median ratio {summary['median_ratio']:.2f}, worst {summary['worst_ratio']:.2f}, "
        f"sum over cases {summary['total_ratio']:.2f} (after / before)"
    )
    write_report(args, cores, rows, summary)
    return 0


def write_report(
    args: argparse.Namespace,
    cores: dict[str, tuple[Path, str]],
    rows: list[dict[str, Any]],
    summary: dict[str, float],
) -> None:
    from frisicp_bench import script

    threads = f"OMP_NUM_THREADS={args.threads}" if args.threads else "OpenMP's default threads"
    command = script.command_line(args)
    lines = [
        "# Core speed before and after: `register` on "
        + (
            (
                "cold scenes onto their 30-60 % crops (trustworthy.py's)"
                if args.reverse
                else "cold 30-60 % crops of real scenes (trustworthy.py's)"
            )
            if args.crops
            else "furnished rooms and their 30 % crops, both ways (structured_scenes.py's)"
            if args.rooms
            else "the full-overlap cases of `make bench`"
        )
        + ", interleaved",
        "",
        f"Start: {'warm, 2 deg / 2 % off the truth' if args.warm else 'cold'}.",
        "",
        f"Generated by `{command}` on {date.today().isoformat()} ({platform.machine()}, {os.cpu_count()} CPUs, "
        f"Python {platform.python_version()}, {threads}); medians of {args.repeats} runs per case, the two "
        "revisions alternating case by case in one session (see the script's docstring).",
        "",
        f"- before: {cores['before'][1]}",
        f"- after: {cores['after'][1]}",
        f"- load average {summary['load_average_start']:.2f} at the start, {summary['load_average_end']:.2f} at the "
        "end: the machine is shared, so absolute times are inflated and noisy; the ratios are what this measures.",
        "",
        f"**after / before: median over the {len(rows)} cases {summary['median_ratio']:.2f}, worst case "
        f"{summary['worst_ratio']:.2f}, total time {summary['total_ratio']:.2f}** (median register "
        f"{summary['median_before_ms']:.0f} ms before, {summary['median_after_ms']:.0f} ms after).",
        "",
        f"| {'case' if args.crops or args.rooms else 's'} | before ms | after ms | after / before "
        "| before: worst rotation error (deg), scale error | after: same |",
        "|---|---|---|---|---|---|",
    ]
    for r in rows:
        lines.append(
            f"| {r['case']} | {r['before_ms']:.1f} | {r['after_ms']:.1f} | {r['ratio']:.2f} | "
            f"{r['before_rotation_deg']:.1e}, {r['before_scale_error']:.1e} | "
            f"{r['after_rotation_deg']:.1e}, {r['after_scale_error']:.1e} |"
        )
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text("\n".join(lines) + "\n")
    document = {
        "command": command,
        "before": cores["before"][1],
        "after": cores["after"][1],
        "summary": summary,
        "rows": rows,
    }
    args.out.with_suffix(".json").write_text(json.dumps(document, indent=1) + "\n")
    print(f"wrote {args.out} and {args.out.with_suffix('.json')}")


if __name__ == "__main__":
    # A worker dispatches before anything imports frisicp_bench, which needs today's core.
    sys.exit(worker(sys.argv[2]) if sys.argv[1:2] == [WORKER] else main())
