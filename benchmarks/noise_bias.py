"""Bias and spread against the noise: the same depth frames, fresh noise draws, cold registrations.

The stated covariance (``RegistrationResult.uncertainty``) is sized by split halves of the clouds
as they are (``frisicp_core.refine.uncertainty_of``): it measures how the estimate varies with the
noise of the points, not an error every noise draw shares. This script separates the two. A pair
of overlapping depth frames is built as ``depth_sensor.py --occlusion --sensor-frames`` builds
its frames cases (``frisicp_bench.sensor.sensed_frames_case``: each frame re-sampled from its own
half of a real scene, seen by its own camera with occlusion, in the camera's frame, depth steps
quantised in disparity, noise along the rays growing with the range squared), and then built
again with the noise alone drawn afresh (``noise_rng``: the same points, cameras, depth steps
and truth). Each draw is capped at 10,000 points as the node does and registered cold with the
default config. Per frame pair and noise level (sigma along the rays, a share of the scene's
diagonal at the median range; ``depth_sensor.py`` uses 0.001, 0.003, 0.005 and 0.007):

- the *bias*: the mean over the draws of the signed scale error, log(s / s_true);
- the *spread*: its standard deviation over the draws;
- the median stated sigma of the scale, and how many draws lie within 3 of their own sigmas;
- at the highest noise, the same with the noise on one cloud only (data or model).

A bias that grows faster than the spread is an error the split halves share, which the
covariance sees only through its widening factors (README, "Depth-sensor noise": the 3-sigma
misses of ``depth_sensor.py --noise 0.007``).

Usage: python benchmarks/noise_bias.py [--jobs 2] [--draws 6] [--data DIR] [--out docs/noise_bias.md]
       python benchmarks/noise_bias.py --quick   # one frame pair, two levels, two draws -> build/
Exits 0 without measuring when the data folder is absent, saying so.
"""

from __future__ import annotations

import os

os.environ.setdefault("OMP_NUM_THREADS", "1")  # before numpy and pykdtree load

import functools
import statistics
import sys
import zlib
from pathlib import Path
from typing import Any

import numpy as np

from frisicp_bench import script
from frisicp_bench.metrics import pose_errors
from frisicp_bench.report import case_record, three_sigma_bounds, within_three_sigma, write_report
from frisicp_bench.scenes import object_cloud
from frisicp_bench.sensor import sensed_frames_case, visible
from frisicp_core import downsample, register

TITLE = "Bias and spread against the noise: one pair of depth frames, fresh noise draws"
CAP = 10_000
# (scene, depth step, shift between the frames): depth_sensor.py's frames cases.
PAIRS = (
    ("rs1.pcd", 0.005, 0.1),
    ("bun_zipper.ply", 0.005, 0.2),
    ("dragon1.xyz", 0.01, 0.2),
    ("dragon2.xyz", 0.01, 0.3),
)
NOISES = (0.0, 0.001, 0.003, 0.005, 0.007)
BOTH = ("data", "model")


def tasks(quick: bool, draws: int) -> list[tuple[str, float, float, float, tuple[str, ...], int]]:
    """(scene, step, shift, noise, noisy clouds, draw) of every registration: each pair at every
    noise level with both clouds noisy, and at the highest with one (one draw without noise)."""
    pairs, noises = (PAIRS[:1], (0.0, NOISES[-1])) if quick else (PAIRS, NOISES)
    draws = 2 if quick else draws
    chosen = []
    for scene, step, shift in pairs:
        for noise in noises:
            for noisy in [BOTH] + ([("data",), ("model",)] if noise == noises[-1] else []):
                for draw in range(draws if noise > 0 else 1):
                    chosen.append((scene, step, shift, noise, noisy, draw))
    return chosen


def measure(task: tuple[str, float, float, float, tuple[str, ...], int], data_dir: Path) -> dict[str, Any]:
    """One noise draw of one frame pair registered cold: signed scale error, sigmas, verdict."""
    scene_name, step, shift, noise, noisy, draw = task
    # The case's own stream fixes the frames; the noise comes from the draw's.
    rng = np.random.default_rng(zlib.crc32(f"noise bias/{scene_name}/{step}/{shift}".encode()))
    case = sensed_frames_case(
        object_cloud(data_dir, scene_name),
        Path(scene_name).stem,
        step,
        shift,
        noise,
        rng,
        lambda points, camera: visible(points, camera),
        noise_rng=np.random.default_rng([draw, 1]),
        noisy=noisy,
    ).in_sensor_frames()
    assert case.truth is not None
    data, model = downsample(case.data, CAP, rng), downsample(case.model, CAP, rng)
    result = register(data, model)
    return case_record(
        pose_errors(result.similarity, case.truth, data, case.model_diagonal),
        result,
        scene=scene_name,
        step=step,
        shift=shift,
        noise=noise,
        noisy="+".join(noisy),
        draw=draw,
        scale_signed=float(np.log(result.similarity.scale / case.truth.scale)),
        three_sigma=three_sigma_bounds(result, case.model_diagonal),
    )


def summarise(records: list[dict[str, Any]]) -> tuple[list[str], list[list[object]]]:
    header = [
        "frames",
        "noise",
        "noisy",
        "draws",
        "bias (mean scale error)",
        "bias less the noiseless error",
        "spread (sd)",
        "bias / spread",
        "median sigma of scale",
        "within 3 sigma (scale)",
        "within 3 sigma (all)",
        "right",
        "reliable",
        "wrong and reliable",
    ]
    rows: list[list[object]] = []
    groups: dict[tuple[str, float, float, float, str], list[dict[str, Any]]] = {}
    for entry in records:
        key = (entry["scene"], entry["step"], entry["shift"], entry["noise"], entry["noisy"])
        groups.setdefault(key, []).append(entry)
    noiseless = {key[:3]: group[0]["scale_signed"] for key, group in groups.items() if key[3] == 0.0}
    for (scene, step, shift, noise, noisy), group in groups.items():
        signed = [e["scale_signed"] for e in group]
        bias = statistics.fmean(signed)
        clean = noiseless.get((scene, step, shift))
        spread = statistics.stdev(signed) if len(signed) > 1 else float("nan")
        sized = [e for e in group if e["three_sigma"] is not None]
        sigma = statistics.median(e["three_sigma"][1] / 3 for e in sized) if sized else float("nan")
        rows.append(
            [
                f"{Path(scene).stem}, step {100 * step:g} %, shift {shift:g}",
                f"{noise:g}",
                noisy,
                len(group),
                f"{100 * bias:+.3f} %",
                "-" if clean is None or noise == 0.0 else f"{100 * (bias - clean):+.3f} %",
                "-" if np.isnan(spread) else f"{100 * spread:.3f} %",
                "-" if np.isnan(spread) or spread == 0 else f"{abs(bias) / spread:.1f}",
                f"{100 * sigma:.3f} %",
                f"{sum(within_three_sigma(e)[1] for e in sized)} of {len(sized)}",
                f"{sum(all(within_three_sigma(e)) for e in sized)} of {len(sized)}",
                sum(e["success"] for e in group),
                sum(e["reliable"] for e in group),
                sum(e["reliable"] and not e["success"] for e in group),
            ]
        )
    return header, rows


def main(argv: list[str] | None = None) -> int:
    command = script.parser(
        __file__, __doc__, "one frame pair, two noise levels, two draws", data=True, report=True
    )
    command.add_argument("--jobs", type=int, default=2, help="worker processes (default 2)")
    command.add_argument("--draws", type=int, default=6, help="noise draws per level (default 6)")
    args = script.parse(command, argv)
    if not (args.data / "real").is_dir() or not (args.data / "bunny").is_dir():
        return script.skip(args, f"no data: {args.data}/real and {args.data}/bunny are needed")
    records = script.map_cases(
        args, functools.partial(measure, data_dir=args.data), tasks(args.quick, args.draws), _line
    )
    if records is None:
        return 0
    header, rows = summarise(records)
    wrong = sum(e["reliable"] and not e["success"] for e in records)
    summary = (
        f"{len(records)} registrations, {wrong} wrong and reliable. Per frame pair and noise level:"
        " the mean signed scale error over the draws (bias) against its standard deviation"
        " (spread), which is what split halves of one draw can measure."
    )
    write_report(args.out, TITLE, script.command_line(args), summary, (header, rows), records)
    return 0


def _line(entry: dict[str, Any]) -> str:
    return (
        f"{entry['scene']} noise {entry['noise']:g} ({entry['noisy']}) draw {entry['draw']}:"
        f" scale {100 * entry['scale_signed']:+.3f} %"
        f" {'reliable' if entry['reliable'] else 'refused'}"
    )


if __name__ == "__main__":
    sys.exit(main())
