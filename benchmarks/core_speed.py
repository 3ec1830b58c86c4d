"""Speed of frisicp_core.register in full-resolution aligned bidirectional passes, cold and warm.

Protocol (issue 10): the bunny reconstruction (35,947 points) against a copy of itself scaled by
s in {0.1, 0.3, ..., 2.9}, rotated 10 degrees and shifted. Each case is registered

- cold: ``register(data, model)`` with the default configuration;
- warm: from an estimate 2 degrees (about a random axis) and 2 % (in scale) off the truth, as a
  tracking node starts from its previous answer.

The unit is one *aligned pass*: build a KD-tree on each set and query every point of each set
against the other once, with the data already on the model (pykdtree, the library's KD-tree;
the cheapest a pass can be). It is timed in the same run, interleaved with the registrations, so
load on this shared machine slows both alike; times are medians of ``--repeats`` runs. Targets:
cold <= 5 passes and warm <= 3 passes (medians over the scales), every case accurate (rotation
< 1 degree, scale < 1 %).

``frisicp-lean`` runs the same cases with ``RegistrationConfig(probe=False, polish=False)``:
ICP down the levels without the probes, the point-to-plane polish and the uncertainty (so
without the verdict's tolerance check), what a user who trades those for speed gets.

``frisicp-prepared`` runs them with the default configuration against one ``PreparedModel`` of
the bunny, made before the first case and kept for the whole run, as the node keeps its latched
map and ``frisicp bag`` its model: what the model alone gives (its order, trees, levels,
normals and curvatures) is derived once, not per call. Its first call, which fills the model's
caches, is one of the repeats of the first scale; the medians are what a tracking call costs.

When Open3D imports, its scaled point-to-point ICP (``registration_icp`` with
``with_scaling=True``, correspondence distance = the model's size, 100 iterations at most) runs
on the same cases, from the identity (cold, as the paper's baselines) and from the same warm
start, side by side.

Usage: OMP_NUM_THREADS=1 python benchmarks/core_speed.py [--repeats 5] [--data DIR] [--out docs/core_speed.md]
(``make bench`` does this.) ``--quick``: 2 scales, one run each -> build/. Exits 0 without
measuring when the data folder is absent, saying so.
"""

from __future__ import annotations

import json
import os
import platform
import statistics
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass
from datetime import date
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from pykdtree.kdtree import KDTree

from frisicp_core import (
    RegistrationConfig,
    Similarity,
    axis_angle_rotation,
    register,
    rotation_angle,
)

if TYPE_CHECKING:  # imported where used: speed_ab.py's workers may hold a core without it
    from frisicp_core import PreparedModel

BUNNY = Path("bunny") / "bun_zipper.ply"  # in the data folder
SCALES = [round(0.1 + 0.2 * k, 1) for k in range(15)]
COLD_TARGET, WARM_TARGET = 5.0, 3.0


@dataclass
class Run:
    """One method on one case: median seconds, passes, and the errors of the last run."""

    method: str
    start: str  # "cold" or "warm"
    scale: float
    seconds: float
    passes: float
    rotation_deg: float
    scale_error: float
    reliable: bool | None  # frisicp_core's verdict (None for Open3D)

    @property
    def accurate(self) -> bool:
        return self.rotation_deg < 1.0 and self.scale_error < 0.01


def aligned_pass(data: np.ndarray, model: np.ndarray) -> None:
    KDTree(data).query(model, k=1)
    KDTree(model).query(data, k=1)


def warm_start(truth: Similarity, rng: np.random.Generator) -> Similarity:
    """The truth turned by 2 degrees about a random axis and scaled by 1.02 (about the data)."""
    turn = axis_angle_rotation(rng.normal(size=3), np.deg2rad(2.0))
    return Similarity(truth.scale * 1.02, turn @ truth.rotation, truth.translation)


def forward_similarity(scale: float) -> Similarity:
    """The case at ``scale``: the data is the bunny scaled by it, turned 10 deg and shifted."""
    return Similarity(scale, axis_angle_rotation([0.3, 1.0, 0.2], np.deg2rad(10.0)), [0.01, -0.02, 0.015])


def open3d_registration() -> Callable[[np.ndarray, np.ndarray, Similarity | None], Similarity] | None:
    # Imported here: speed_ab.py's workers import this module next to an older frisicp_core.
    from frisicp_bench.methods import open3d_available, open3d_transformation

    if not open3d_available():
        return None

    def run(data: np.ndarray, model: np.ndarray, start: Similarity | None) -> Similarity:
        return Similarity.from_matrix(open3d_transformation(data, model, start))

    return run


def errors(estimate: Similarity | None, truth: Similarity) -> tuple[float, float]:
    if estimate is None:
        return float("inf"), float("inf")
    return (
        float(np.rad2deg(rotation_angle(estimate.rotation.T @ truth.rotation))),
        abs(estimate.scale / truth.scale - 1),
    )


def measure(model: np.ndarray, repeats: int, scales: Sequence[float]) -> list[Run]:
    # Imported here: speed_ab.py's workers import this module next to an older frisicp_core.
    from frisicp_core import PreparedModel

    rng = np.random.default_rng(0)
    open3d = open3d_registration()
    prepared = PreparedModel(model)
    runs = []
    header = f"{'s':>4} {'start':>5} {'method':>16} {'ms':>8} {'passes':>7} {'rot deg':>9} {'scale err':>9}"
    print(header, flush=True)
    for scale in scales:
        forward = forward_similarity(scale)
        data, truth = forward.apply(model), forward.inverse()
        aligned = truth.apply(data)
        starts = {"cold": None, "warm": warm_start(truth, rng)}
        methods: dict[str, Callable[[Similarity | None], tuple[Similarity | None, bool | None]]] = {
            "frisicp": lambda start: _frisicp(data, model, start),
            "frisicp-lean": lambda start: _frisicp(data, model, start, lean=True),
            "frisicp-prepared": lambda start: _frisicp(data, prepared, start),
        }
        if open3d is not None:
            methods["open3d"] = lambda start: _open3d(open3d, data, model, start)
        times: dict[tuple[str, str], list[float]] = {(m, s): [] for m in methods for s in starts}
        passes: list[float] = []
        last: dict[tuple[str, str], tuple[Similarity | None, bool | None]] = {}
        for _ in range(repeats):  # interleaved: one pass, then every method and start once
            began = time.perf_counter()
            aligned_pass(aligned, model)
            passes.append(time.perf_counter() - began)
            for name, method in methods.items():
                for start_name, start in starts.items():
                    began = time.perf_counter()
                    last[(name, start_name)] = method(start)
                    times[(name, start_name)].append(time.perf_counter() - began)
        unit = statistics.median(passes)
        for (name, start_name), seconds in times.items():
            estimate, reliable = last[(name, start_name)]
            rotation_deg, scale_error = errors(estimate, truth)
            run = Run(
                name,
                start_name,
                scale,
                statistics.median(seconds),
                statistics.median(seconds) / unit,
                rotation_deg,
                scale_error,
                reliable,
            )
            runs.append(run)
            print(
                f"{scale:4.1f} {start_name:>5} {name:>16} {run.seconds * 1e3:8.1f} {run.passes:7.2f} "
                f"{rotation_deg:9.2e} {scale_error:9.1e}",
                flush=True,
            )
    return runs


def _frisicp(
    data: np.ndarray, model: np.ndarray | PreparedModel, start: Similarity | None, lean: bool = False
) -> tuple[Similarity, bool]:
    config = (
        RegistrationConfig(initial=start, probe=False, polish=False)
        if lean
        else RegistrationConfig(initial=start)
    )
    result = register(data, model, config)
    return result.similarity, result.reliable


def _open3d(
    run, data: np.ndarray, model: np.ndarray, start: Similarity | None
) -> tuple[Similarity | None, None]:
    try:
        return run(data, model, start), None
    except ValueError:  # a collapsed scale: det <= 0
        return None, None


def summary(runs: list[Run]) -> list[str]:
    lines = []
    for method in sorted({r.method for r in runs}):
        for start, target in (("cold", COLD_TARGET), ("warm", WARM_TARGET)):
            chosen = [r for r in runs if r.method == method and r.start == start]
            median = statistics.median(r.passes for r in chosen)
            accurate = sum(r.accurate for r in chosen)
            verdict = (
                f" (target <= {target:g}: {'met' if median <= target else 'MISSED'})"
                if method == "frisicp"
                else ""
            )
            lines.append(
                f"{method} {start}: median {median:.2f} passes{verdict}, worst {max(r.passes for r in chosen):.2f};"
                f" median {statistics.median(r.seconds for r in chosen) * 1e3:.0f} ms;"
                f" accurate {accurate}/{len(chosen)}"
            )
    return lines


def write_report(path: Path, command: str, runs: list[Run], lines: list[str], repeats: int) -> None:
    machine = f"{platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}"
    threads = os.environ.get("OMP_NUM_THREADS", "OpenMP default")
    with_open3d = any(r.method == "open3d" for r in runs)
    text = [
        "# Core speed: register in aligned bidirectional passes, cold and warm",
        "",
        f"Generated by `{command}` on {date.today().isoformat()} ({machine}; "
        f"OMP_NUM_THREADS={threads}); medians of {repeats} interleaved runs. Bunny reconstruction "
        "(35,947 points) against a copy scaled by s, turned 10 deg and shifted; default "
        "`RegistrationConfig()` (frisicp-lean: `probe=False, polish=False`; frisicp-prepared: the default against one `PreparedModel` of the bunny kept for the run). Warm: started 2 deg / 2 % off the truth. One pass = two pykdtree "
        "builds and two full queries with the data aligned, timed in the same run.",
        "",
        *[f"- {line}" for line in lines],
        "",
        "| s | start | method | ms | passes | rotation error deg | scale error |",
        "|---|---|---|---|---|---|---|",
    ]
    for r in runs:
        text.append(
            f"| {r.scale:.1f} | {r.start} | {r.method} | {r.seconds * 1e3:.1f} | {r.passes:.2f} | "
            f"{r.rotation_deg:.1e} | {r.scale_error:.1e} |"
        )
    if not with_open3d:
        text += ["", "Open3D was not installed for this run (`pip install -e '.[open3d]'`)."]
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("\n".join(text) + "\n")
    path.with_suffix(".json").write_text(json.dumps([asdict(r) for r in runs], indent=1) + "\n")


def main(argv: list[str] | None = None) -> int:
    # Imported here: speed_ab.py's workers import this module next to an older frisicp_core,
    # which may lack read_points and whose frisicp_bench would not match.
    from frisicp_bench import script
    from frisicp_core import read_points

    parser = script.parser(__file__, __doc__, "2 scales, one run each", data=True, report=True, repeats=5)
    args = script.parse(parser, argv)
    bunny = args.data / BUNNY
    if not bunny.exists():
        return script.skip(args, f"no data: {bunny} is absent")
    scales, repeats = (script.SMOKE_SCALES, 1) if args.quick else (SCALES, args.repeats)
    runs = measure(read_points(bunny), repeats, scales)
    lines = summary(runs)
    print("\n".join(lines))
    write_report(args.out, script.command_line(args), runs, lines, repeats)
    return 0


if __name__ == "__main__":
    sys.exit(main())
