"""How far apart may the frames of a scan and its map be turned? Default config, real scans.

A cold start finds partial overlap from hypotheses that leave the data in place (its frame
"roughly aligned" with the model's), plain and turned by ``hypotheses.IN_PLACE_TURN`` about each
axis. This measures what "roughly" means: each real scan (bun090, bun180, bun270, bun315, placed
by bun.conf) is registered onto the bunny reconstruction after a turn of 0, 15, ..., 90 deg about
a seeded random axis through its centroid, at scales 0.5, 1 and 2 about it, with two seeded axes
per angle (4 scans x 7 angles x 3 scales x 2 axes = 168 cases). Scored like ``frisicp bench``
(rotation < 1 deg, scale < 1 %, translation < 0.5 % of the map's diagonal), one OpenMP thread.

Usage: python benchmarks/turned_frames.py [--seed 0] [--data DIR] [--out docs/turned_frames.md]
       python benchmarks/turned_frames.py --quick   # bun090 turned 0 and 45 deg, scale 1, one axis -> build/
Exits 0 without measuring when the data folder is absent, saying so.
"""

from __future__ import annotations

import os

os.environ["OMP_NUM_THREADS"] = "1"  # before numpy and pykdtree load

import sys
import zlib

import numpy as np

from frisicp_bench import script
from frisicp_bench.families import MAP_SCANS, scan_to_map_family
from frisicp_bench.metrics import pose_errors
from frisicp_bench.report import case_record, write_report, wrong_but_reliable
from frisicp_core import RegistrationConfig, Similarity, axis_angle_rotation, register

TITLE = "A scan in its map with the frames turned apart, default config"
ANGLES_DEG = (0, 15, 30, 45, 60, 75, 90)
SCALES = (0.5, 1.0, 2.0)
AXES = 2


def main(argv: list[str] | None = None) -> int:
    quick = "bun090 in the map turned 0 and 45 deg about one axis, at scale 1"
    args = script.parse(script.parser(__file__, __doc__, quick, data=True, seed=True, report=True), argv)
    scans, angles, scales, axes = (
        (MAP_SCANS[:1], (0, 45), (1.0,), 1) if args.quick else (MAP_SCANS, ANGLES_DEG, SCALES, AXES)
    )
    families = script.load_data(args, lambda data: [scan_to_map_family(data, scan) for scan in scans])
    if families is None:
        return 0
    records = []
    for family in families:
        centre = family.data.mean(axis=0)
        for angle in angles:
            for scale in scales:
                for axis_index in range(axes):
                    rng = np.random.default_rng([args.seed, zlib.crc32(family.name.encode()), axis_index])
                    rotation = axis_angle_rotation(rng.normal(size=3), np.radians(angle))
                    g = Similarity.about(centre, scale, rotation)
                    data = g.apply(family.data)
                    result = register(data, family.model, RegistrationConfig())
                    errors = pose_errors(result.similarity, g.inverse(), data, family.size)
                    records.append(
                        case_record(
                            errors, result, family=family.name, turn_deg=angle, scale=scale, axis=axis_index
                        )
                    )
                    print(
                        f"{family.name:14s} turned {angle:3d} deg s={scale:<4} axis {axis_index} "
                        f"{'ok  ' if errors.success else 'FAIL'} rot {errors.rotation_deg:7.2f} deg "
                        f"scale {100 * errors.scale:6.2f} %  {result.seconds:.2f} s",
                        flush=True,
                    )
    rows = []
    for family in families:
        cells = []
        for angle in angles:
            group = [r for r in records if r["family"] == family.name and r["turn_deg"] == angle]
            cells.append(f"{sum(r['success'] for r in group)}/{len(group)}")
        rows.append([family.name, *cells])
    totals = []
    for angle in angles:
        group = [r for r in records if r["turn_deg"] == angle]
        totals.append(f"**{sum(r['success'] for r in group)}/{len(group)}**")
    rows.append(["all", *totals])
    summary = (
        f"Strict successes per turn of the scan ({len(scales)} scales x {axes} axes per cell); "
        f"{wrong_but_reliable(records)} of the failures were called reliable."
    )
    header = ["scan → map", *(f"{a}°" for a in angles)]
    write_report(args.out, TITLE, script.command_line(args), summary, (header, rows), records)
    return 0


if __name__ == "__main__":
    sys.exit(main())
