"""What a warm start costs the core on the node benchmark's clouds, by where it starts (no ROS).

    OMP_NUM_THREADS=1 .venv/bin/python benchmarks/tracking_warm_start.py [--points 10000] [--frames 60]

The clouds of ``benchmarks/node_latency.py`` (a 100k-point model capped like the node caps it,
fresh 100k-point noisy samples of the surface seen by a moving sensor), registered by
``frisicp_core.register`` with ``initial`` set to: the truth itself, the previous scan's result
(``motion_model: none``), and the node's constant-velocity prediction. Prints CPU time (median,
p95, max), the iterations per level (most common patterns) and the start's error against the
result, for a sensor at rest and a moving one. It shows where the node's time goes once the
node's own costs are gone: a start a few standard errors away from the scan's own optimum makes
the finest level iterate ~5 times (each a full-resolution bidirectional KD-tree pass) instead of
once. KD-tree passes: query points per full bidirectional pass (benchmarks/query_count.py), the
deterministic part of the cost; the bunny cases of `make bench` are counted the same way.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from collections import Counter
from dataclasses import replace
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from core_speed import BUNNY, SCALES, forward_similarity, warm_start
from node_latency import NOISE, moving_truth, static_truth
from query_count import counting_queries

from frisicp_core import RegistrationConfig, bumpy_surface, downsample, register
from frisicp_core.io import read_points
from frisicp_ros.stream.motion import MotionTracker


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--points", type=int, default=10_000, help="the cap (the node's max_points)")
    parser.add_argument("--frames", type=int, default=60, help="scans at 10 Hz per case")
    args = parser.parse_args()
    model = downsample(bumpy_surface(100_000, seed=0), args.points, np.random.default_rng(0))
    rng = np.random.default_rng(100)
    pool = bumpy_surface(500_000, seed=1) + rng.normal(scale=1.3 * NOISE, size=(500_000, 3))
    for motion in ("static", "moving"):
        truth_at = static_truth() if motion == "static" else moving_truth()
        truths = [truth_at(k / 10) for k in range(args.frames)]
        scans = [
            downsample(
                truth.inverse().apply(pool[rng.choice(len(pool), 100_000, replace=False)]),
                args.points,
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
                if k >= 3:
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
    bunny_passes()


def bunny_passes() -> None:
    """make bench's bunny cases (benchmarks/core_speed.py), cold and warm 2 deg / 2 % off, in
    KD-tree query points per full pass: the part of a registration's cost that is not fixed."""
    if not BUNNY.exists():
        print(f"bunny: skipped, {BUNNY} is absent")
        return
    model = read_points(BUNNY)
    rng = np.random.default_rng(0)
    for start in ("cold", "warm"):
        passes, patterns = [], Counter()
        for scale in SCALES:
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
    main()
