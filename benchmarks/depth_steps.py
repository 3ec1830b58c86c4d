"""Depth steps: does frisicp_core.find_depth_steps find a depth camera's shells, and nothing else?

The node and ``frisicp bag`` look at the data clouds for coarse depth steps (README, "Depth-sensor
noise"; ``frisicp_ros.stream.depth_check``) and advise ``voxel_mode: centroid`` when they find
them. This measures the finder on clouds in their sensor's frame, as a camera driver publishes
them:

- *sensed views*: a box of 40 % of a real scene, seen by a depth camera
  (:func:`frisicp_bench.sensor.depth_sensor`: noise along the ray of 0.1 % of the scene's
  diagonal at the median range, depth steps of 0, 0.25, 0.5, 1, 2 and 4 % of it there, in
  disparity), moved so the camera is the origin; blurred (the noise after the quantisation) and
  on shells (before it: every depth exactly on a shell), each with and without occlusion
  (:func:`frisicp_bench.sensor.visible`), three draws each. Scenes: the development ones (rs1,
  the bunny, the dragon) and three held-out clouds (the chef figure, the second dragon sampling,
  a real bunny scan). A found step is right when within 5 % of the sensor's step at the median
  range the finder reports;
- *real scans* as they are: every cloud of the data folder (laser scans and an RGB-D frame whose
  depth has no disparity steps at this scale): nothing coarse may be found.

Coarse (the advice given) is a step of at least ``frisicp_core.depth_steps.COARSE_SHARE`` (1 %)
of the cloud's own bounding-box diagonal; a 40 % view is smaller than its scene, so a step of
1 % of the scene is about 1.5 % of the view.

Usage: python benchmarks/depth_steps.py [--data DIR] [--out docs/depth_steps.md]
       python benchmarks/depth_steps.py --quick   # rs1 at steps 0 and 2 %, one draw -> build/
Exits 0 without measuring when the data folder is absent, saying so.
"""

from __future__ import annotations

import statistics
import sys
import time
import zlib
from pathlib import Path
from typing import Any

import numpy as np

from frisicp_bench import script
from frisicp_bench.metrics import model_size
from frisicp_bench.report import write_report
from frisicp_bench.scenes import box_crop, object_cloud
from frisicp_bench.sensor import camera_facing, depth_sensor, visible
from frisicp_core import read_points
from frisicp_core.depth_steps import find_depth_steps

TITLE = "Depth steps: a depth camera's shells found in clouds in its frame, and nothing else"
SCENES = ("rs1.pcd", "bun_zipper.ply", "dragon1.xyz", "chef.pcd", "dragon2.xyz", "bunny_part2.xyz")
HELD_OUT = ("chef.pcd", "dragon2.xyz", "bunny_part2.xyz")
STEPS = (0.0, 0.0025, 0.005, 0.01, 0.02, 0.04)
NOISE = 0.001
DRAWS = 3
VIEW_SHARE = 0.4
# Every cloud of the data folder, as it is (relative to it).
REAL_SCANS = (
    "real/rs1.pcd",
    "real/cturtle.pcd",
    "real/chef.pcd",
    "real/dragon1.xyz",
    "real/dragon2.xyz",
    "real/bunny_part1.xyz",
    "real/bunny_part2.xyz",
    "bunny/bun_zipper.ply",
    "bunny/bun000.ply",
    "bunny/bun045.ply",
    "bunny/bun090.ply",
    "bunny/bun180.ply",
    "bunny/bun270.ply",
    "bunny/bun315.ply",
)
RIGHT_STEP = 0.05


def sensed_view(
    scene: np.ndarray, step: float, on_shells: bool, occlusion: bool, rng: np.random.Generator
) -> tuple[np.ndarray, float]:
    """A view of ``scene`` as a depth camera at the origin reports it, and the camera's step at
    the median range of the points it measured (the step grows with the range squared)."""
    diagonal = model_size(scene)
    view = box_crop(scene, VIEW_SHARE, rng)
    camera = camera_facing(view, rng)
    seen = visible(view, camera) if occlusion else view
    median = float(np.median(np.linalg.norm(seen - camera, axis=1)))
    sensed = depth_sensor(seen, camera, NOISE * diagonal, step * diagonal, rng, on_shells) - camera
    return sensed, step * diagonal / median**2


def sensed_record(
    data_dir: Path, scene_name: str, step: float, on_shells: bool, occlusion: bool, draw: int
) -> dict[str, Any]:
    salt = f"{scene_name}/{step}/{on_shells}/{occlusion}/{draw}"
    rng = np.random.default_rng(zlib.crc32(salt.encode()))
    cloud, quantum = sensed_view(object_cloud(data_dir, scene_name), step, on_shells, occlusion, rng)
    began = time.perf_counter()
    found = find_depth_steps(cloud)
    seconds = time.perf_counter() - began
    record: dict[str, Any] = {
        "scene": scene_name,
        "held_out": scene_name in HELD_OUT,
        "step": step,
        "on_shells": on_shells,
        "occlusion": occlusion,
        "draw": draw,
        "points": int(cloud.shape[0]),
        "seconds": seconds,
        "found": found is not None,
        "coarse": bool(found is not None and found.coarse),
    }
    if found is not None:
        truth = quantum * found.median_depth**2 if found.depth == "range" else float("nan")
        record.update(
            depth=found.depth,
            found_step=found.step,
            true_step=truth,
            share=found.share,
            coherence=found.coherence,
            step_right=bool(abs(found.step / truth - 1) <= RIGHT_STEP) if step > 0 else False,
        )
    return record


def real_record(data_dir: Path, relative: str) -> dict[str, Any]:
    points = read_points(data_dir / relative)
    began = time.perf_counter()
    found = find_depth_steps(points)
    seconds = time.perf_counter() - began
    return {
        "scan": relative,
        "points": int(points.shape[0]),
        "seconds": seconds,
        "found": "none" if found is None else str(found),
        "coarse": bool(found is not None and found.coarse),
    }


def main(argv: list[str] | None = None) -> int:
    quick = "rs1 at steps 0 and 2 %, one draw, and rs1 as it is"
    args = script.parse(script.parser(__file__, __doc__, quick, data=True, report=True), argv)
    if not (args.data / REAL_SCANS[0]).exists():
        return script.skip(args, f"no data: {args.data / REAL_SCANS[0]} is absent")
    scenes, steps, draws, scans = (
        (SCENES[:1], (0.0, 0.02), 1, REAL_SCANS[:1]) if args.quick else (SCENES, STEPS, DRAWS, REAL_SCANS)
    )
    records = []
    for scene_name in scenes:
        for step in steps:
            for on_shells in (False, True):
                for occlusion in (False, True):
                    for draw in range(draws):
                        record = sensed_record(args.data, scene_name, step, on_shells, occlusion, draw)
                        records.append(record)
                        print(
                            f"{scene_name:16s} step {step:6.2%} {'shells ' if on_shells else 'blurred'}"
                            f" {'occluded' if occlusion else '        '} {record['points']:6d} points:"
                            f" {'coarse' if record['coarse'] else 'found' if record['found'] else 'none'}"
                            f" {record.get('share', 0):.4f} {record.get('coherence', 0):.2f}",
                            file=sys.stderr,
                            flush=True,
                        )
    reals = [real_record(args.data, relative) for relative in scans]
    rows = []
    for step in steps:
        for held_out in (False, True):
            group = [r for r in records if r["step"] == step and r["held_out"] == held_out]
            if not group:
                continue
            for on_shells in (False, True):
                chosen = [r for r in group if r["on_shells"] == on_shells]
                shares = [r["share"] for r in chosen if r["found"]]
                rows.append(
                    [
                        f"{step:.2%}",
                        "held-out" if held_out else "development",
                        "on shells" if on_shells else "blurred",
                        len(chosen),
                        sum(r["found"] for r in chosen),
                        sum(r.get("step_right", False) for r in chosen) if step > 0 else "-",
                        sum(r["coarse"] for r in chosen),
                        f"{min(shares):.2%}-{max(shares):.2%}" if shares else "-",
                    ]
                )
    false_coarse = sum(r["coarse"] for r in records if r["step"] == 0) + sum(r["coarse"] for r in reals)
    unquantised = sum(r["step"] == 0 for r in records) + len(reals)
    milliseconds = statistics.median(r["seconds"] for r in records + reals) * 1e3
    summary = "\n".join(
        [
            f"Views of {len(scenes)} scenes x {len(steps)} steps x blurred / on shells x with and without"
            f" occlusion x {draws} draws; the real scans as they are. **Coarse steps found in clouds"
            f" without any: {false_coarse} of {unquantised}** ({sum(r['step'] == 0 for r in records)}"
            f" views at step 0 and {len(reals)} real scans). Median time of a call:"
            f" {milliseconds:.1f} ms (at most {max(r['points'] for r in records + reals):,} points, of"
            " which 20,000 are looked at).",
            "",
            "Real scans as they are: "
            + "; ".join(f"{r['scan']} ({r['points']:,} points): {r['found']}" for r in reals)
            + ".",
            "",
            "Per step (shares of the scene's diagonal at the median range): views, steps found,"
            " found within 5 % of the camera's, flagged coarse (the advice), and the steps' shares"
            " of the view's own diagonal:",
        ]
    )
    header = ["step", "clouds", "depths", "views", "found", "step right", "coarse", "share of the view"]
    write_report(args.out, TITLE, script.command_line(args), summary, (header, rows), records + reals)
    return 0


if __name__ == "__main__":
    sys.exit(main())
