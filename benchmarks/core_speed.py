"""Speed of frisicp_core.register against one full-resolution bidirectional nearest-neighbour pass.

Protocol (issue 2): the bunny reconstruction (35,947 points) against a copy of itself scaled by
s in {0.1, 0.3, ..., 2.9}, rotated 10 degrees and shifted. One *pass* = build a KD-tree on each
set and query every point of each set against the other once; timed with scipy's cKDTree
(workers=-1) and with pykdtree, the faster one is the reference. Target: register <= 5 passes
at every s, at full accuracy (rotation < 0.5 deg, scale < 0.5 %).

The pass is timed on the sets as given to ``register`` (misaligned, as the issue defines it) and
also with the data moved onto the model by the true similarity ("aligned pass", the cheapest a
pass can be: every query lands on the surface). Both ratios are printed.

Usage: python benchmarks/core_speed.py [--repeats 5] [--out docs/core_speed.md]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import sys
import time
from datetime import date
from pathlib import Path

import numpy as np
from pykdtree.kdtree import KDTree
from scipy.spatial import cKDTree

from frisicp_core import Similarity, axis_angle_rotation, register, rotation_angle
from frisicp_core.io import read_points

ROOT = Path(__file__).resolve().parents[1]
BUNNY = ROOT.parent / "shared" / "data" / "bunny" / "bun_zipper.ply"
SCALES = [round(0.1 + 0.2 * k, 1) for k in range(15)]


def rotation_10deg() -> np.ndarray:
    return axis_angle_rotation([0.3, 1.0, 0.2], np.deg2rad(10.0))


def pass_pykdtree(a: np.ndarray, b: np.ndarray) -> None:
    KDTree(a).query(b, k=1)
    KDTree(b).query(a, k=1)


def pass_ckdtree(a: np.ndarray, b: np.ndarray) -> None:
    cKDTree(a).query(b, k=1, workers=-1)
    cKDTree(b).query(a, k=1, workers=-1)


def level_breakdown_ms(result) -> tuple[float, list[float]]:
    """(start-up ms, ms per level) from the iteration history: start-up is everything before the
    coarsest level's first iteration (validation, thinning, trees, screening the initial
    hypotheses); a level's time runs from its first iteration to the next level's (or the end)."""
    starts = [next(r.seconds for r in result.history if r.level == k) for k in range(len(result.levels))]
    ends = [*starts[1:], result.seconds]
    return starts[0] * 1e3, [(e - b) * 1e3 for b, e in zip(starts, ends, strict=False)]


def median_seconds(action, repeats: int) -> float:
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        action()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "core_speed.md")
    args = parser.parse_args()
    if not BUNNY.exists():
        print(
            f"core_speed: {BUNNY} is absent; this benchmark needs ../shared/data beside the repo",
            file=sys.stderr,
        )
        return 2

    model = read_points(BUNNY)
    rows = []
    print(
        f"{'s':>4} {'register ms':>12} {'pass pykd':>10} {'pass ckd':>9} {'ratio':>6} "
        f"{'aligned pass':>12} {'ratio':>6} {'rot deg':>9} {'scale err':>9}"
    )
    for scale in SCALES:
        forward = Similarity(scale, rotation_10deg(), [0.01, -0.02, 0.015])
        data = forward.apply(model)
        truth = forward.inverse()
        results = []
        reg = median_seconds(lambda: results.append(register(data, model)), args.repeats)
        pykd = median_seconds(lambda: pass_pykdtree(data, model), args.repeats)
        ckd = median_seconds(lambda: pass_ckdtree(data, model), args.repeats)
        aligned_data = truth.apply(data)
        aligned = median_seconds(lambda: pass_pykdtree(aligned_data, model), args.repeats)
        startup_ms, levels_ms = level_breakdown_ms(results[-1])
        estimate = results[-1].similarity
        rot = float(np.rad2deg(rotation_angle(estimate.rotation.T @ truth.rotation)))
        scale_error = abs(estimate.scale / truth.scale - 1)
        reference = min(pykd, ckd)
        row = dict(
            s=scale,
            register_ms=reg * 1e3,
            pass_pykdtree_ms=pykd * 1e3,
            pass_ckdtree_ms=ckd * 1e3,
            ratio=reg / reference,
            aligned_pass_ms=aligned * 1e3,
            aligned_ratio=reg / aligned,
            rotation_error_deg=rot,
            scale_error=scale_error,
            startup_ms=startup_ms,
            levels_ms=levels_ms,
            final_level_iterations=results[-1].iterations[-1],
            accurate=rot < 0.5 and scale_error < 0.005,
        )
        rows.append(row)
        print(
            f"{scale:4.1f} {reg * 1e3:12.1f} {pykd * 1e3:10.1f} {ckd * 1e3:9.1f} {row['ratio']:6.2f} "
            f"{aligned * 1e3:12.1f} {row['aligned_ratio']:6.2f} {rot:9.2e} {scale_error:9.1e}",
            flush=True,
        )

    med = {
        key: statistics.median(r[key] for r in rows)
        for key in ("register_ms", "pass_pykdtree_ms", "pass_ckdtree_ms", "aligned_pass_ms", "startup_ms")
    }
    final_level = statistics.median(r["levels_ms"][-1] for r in rows)
    final_iterations = statistics.median(r["final_level_iterations"] for r in rows)
    worst = max(r["ratio"] for r in rows)
    worst_aligned = max(r["aligned_ratio"] for r in rows)
    all_accurate = all(r["accurate"] for r in rows)
    summary = (
        f"median register {med['register_ms']:.1f} ms; median pass: pykdtree {med['pass_pykdtree_ms']:.1f} ms, "
        f"cKDTree {med['pass_ckdtree_ms']:.1f} ms, aligned pykdtree {med['aligned_pass_ms']:.1f} ms; "
        f"worst ratio register/pass {worst:.2f} (target <= 5: {'met' if worst <= 5 else 'MISSED'}); "
        f"worst ratio register/aligned pass {worst_aligned:.2f}; all 15 scales accurate: {all_accurate}; "
        f"median breakdown of one register: start-up incl. hypothesis screening {med['startup_ms']:.0f} ms, "
        f"full-resolution level {final_level:.0f} ms ({final_iterations:.0f} iterations + 1 final pass)"
    )
    print(summary)
    write_report(args.out, rows, summary, args.repeats)
    return 0


def write_report(path: Path, rows: list[dict], summary: str, repeats: int) -> None:
    machine = f"{platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}"
    lines = [
        "# Core speed: register vs one bidirectional KD-tree pass",
        "",
        f"Generated by `python benchmarks/core_speed.py` on {date.today().isoformat()} ({machine}); "
        f"medians of {repeats} runs. Bunny reconstruction (35,947 points) against a copy scaled by s, "
        "rotated 10 deg and shifted; default `RegistrationConfig()`.",
        "",
        summary,
        "",
        "| s | register ms | pass pykdtree ms | pass cKDTree ms | register / pass | aligned pass ms | register / aligned pass | rotation error deg | scale error |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        lines.append(
            f"| {r['s']:.1f} | {r['register_ms']:.1f} | {r['pass_pykdtree_ms']:.1f} | {r['pass_ckdtree_ms']:.1f} | "
            f"{r['ratio']:.2f} | {r['aligned_pass_ms']:.1f} | {r['aligned_ratio']:.2f} | "
            f"{r['rotation_error_deg']:.1e} | {r['scale_error']:.1e} |"
        )
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("\n".join(lines) + "\n")
    path.with_suffix(".json").write_text(json.dumps(rows, indent=1) + "\n")


if __name__ == "__main__":
    sys.exit(main())
