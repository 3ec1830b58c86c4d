"""What a warm start costs the core on the node benchmark's clouds, by where it starts (no ROS).

    OMP_NUM_THREADS=1 .venv/bin/python benchmarks/tracking_warm_start.py [--points 10000] [--frames 60] [--data DIR]
    .venv/bin/python benchmarks/tracking_warm_start.py --quick   # 2,000-point clouds, 6 frames, 2 bunny scales

The clouds of ``benchmarks/node_latency.py`` (a 100k-point model capped like the node caps it,
fresh 100k-point noisy samples of the surface seen by a moving sensor), registered by
``frisicp_core.register`` with ``initial`` set to: the truth itself, the previous scan's result
(``motion_model: none``), and the node's constant-velocity prediction. Prints CPU time (median,
p95, max), the iterations per level (most common patterns) and the start's error against the
result, for a sensor at rest and a moving one. It shows where the node's time goes once the
node's own costs are gone: a start a few standard errors away from the scan's own optimum makes
the finest level iterate ~5 times (each a full-resolution bidirectional KD-tree pass) instead of
once. KD-tree passes: query points per full bidirectional pass (frisicp_bench.neighbours), the
deterministic part of the cost; the bunny cases of `make bench` are counted the same way (skipped,
saying so, when the data folder is absent).
"""

from __future__ import annotations

import os
import sys
import time
from collections import Counter
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np
from core_speed import BUNNY, SCALES, forward_similarity, warm_start
from node_latency import NOISE, moving_truth, static_truth

from frisicp_bench import script
from frisicp_bench.neighbours import counting_queries
from frisicp_core import RegistrationConfig, bumpy_surface, downsample, read_points, register
from frisicp_ros.stream.motion import MotionTracker

RAW = 100_000  # points of a scan before the cap: the node benchmark's clouds
FIRST_COUNTED = 3  # frames before it are the tracker's warm-up


def main(argv: list[str] | None = None) -> int:
    quick = "2,000-point clouds, 6 frames; the bunny at 2 scales"
    parser = script.parser(__file__, __doc__, quick, data=True)
    parser.add_argument("--points", type=int, default=10_000, help="the cap (the node's max_points)")
    parser.add_argument("--frames", type=int, default=60, help="scans at 10 Hz per case")
    args = script.parse(parser, argv)
    points, frames, raw = (2000, FIRST_COUNTED + 3, 10_000) if args.quick else (args.points, args.frames, RAW)
    model = downsample(bumpy_surface(raw, seed=0), points, np.random.default_rng(0))
    rng = np.random.default_rng(100)
    pool = bumpy_surface(5 * raw, seed=1) + rng.normal(scale=1.3 * NOISE, size=(5 * raw, 3))
    for motion in ("static", "moving"):
        truth_at = static_truth() if motion == "static" else moving_truth()
        truths = [truth_at(k / 10) for k in range(frames)]
        scans = [
            downsample(
                truth.inverse().apply(pool[rng.choice(len(pool), raw, replace=False)]),
                points,
                np.random.default_rng(0),
            )
            for truth in truths
        ]
        for start in ("truth", "previous result", "constant velocity"):
            tracker = MotionTracker()
            cpu, passes, patterns, start_errors = [], [], Counter(), []
            for k, (truth, scan) in enumerate(zip(truths, scans, strict=True)):
                stamp = k * 100_000_000
                if start == "truth":
                    initial = truth
                elif start == "previous result":
                    initial = tracker.last
                else:
                    initial = tracker.predict(stamp)
                with counting_queries() as queried:
                    began = time.thread_time()
                    result = register(scan, model, replace(RegistrationConfig(), initial=initial))
                    spent = time.thread_time() - began
                    queried_points = queried()
                tracker.update(stamp, result.similarity)
                if k >= FIRST_COUNTED:
                    cpu.append(spent * 1e3)
                    passes.append(queried_points / (len(scan) + len(model)))
                    patterns[result.iterations] += 1
                    gap = initial.inverse() @ result.similarity  # type: ignore[union-attr]
                    start_errors.append((np.rad2deg(gap.rotation_angle()), np.linalg.norm(gap.translation)))
            errors = np.array(start_errors)
            print(
                f"{motion:6s} start={start:17s} cpu ms median {np.median(cpu):5.1f} p95"
                f" {np.percentile(cpu, 95):5.1f} max {max(cpu):5.1f} | KD-tree passes mean"
                f" {np.mean(passes):.2f} p95 {np.percentile(passes, 95):.2f} | start error median"
                f" {np.median(errors[:, 0]):.3f} deg {np.median(errors[:, 1]) * 1e3:.1f} mm |"
                f" iterations {patterns.most_common(4)}",
                flush=True,
            )
    bunny = args.data / BUNNY
    if not bunny.exists():
        return script.skip(args, f"the bunny's passes: {bunny} is absent")
    bunny_passes(bunny, script.SMOKE_SCALES if args.quick else SCALES)
    return 0


def bunny_passes(bunny: Path, scales: Sequence[float]) -> None:
    """make bench's bunny cases (benchmarks/core_speed.py), cold and warm 2 deg / 2 % off, in
    KD-tree query points per full pass: the part of a registration's cost that is not fixed."""
    model = read_points(bunny)
    rng = np.random.default_rng(0)
    for start in ("cold", "warm"):
        passes, patterns = [], Counter()
        for scale in scales:
            forward = forward_similarity(scale)
            initial = None if start == "cold" else warm_start(forward.inverse(), rng)
            with counting_queries() as queried:
                result = register(forward.apply(model), model, RegistrationConfig(initial=initial))
                passes.append(queried() / (2 * len(model)))
            patterns[result.iterations] += 1
        print(
            f"bunny  {start}: KD-tree passes median {np.median(passes):.2f} max {max(passes):.2f}"
            f" | iterations {patterns.most_common(6)}",
            flush=True,
        )


if __name__ == "__main__":
    sys.exit(main())
