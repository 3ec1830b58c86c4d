"""Depth-sensor noise: frames and crops whose errors a structured-light or stereo camera makes.

Every case of ``benchmarks/trustworthy.py`` adds isotropic Gaussian noise; a depth camera errs
along its rays, more with the range, and reports depths on quantised shells
(:mod:`frisicp_bench.sensor`). This script registers, with the default config and both clouds
capped at 10,000 random points (the node's cap):

- *frames*: two overlapping views of a real scene (boxes of 40 %, shifted by a tenth to three
  tenths of their width), each from its own half of the scene's points, seen by its own camera
  (the second moved with its box), the data moved by a small motion
  (:func:`frisicp_bench.sensor.sensed_frames_case`);
- *crop onto scene*: a 30-60 % crop seen by a camera, moved by ``frisicp bench``'s protocol at one
  of the paper's 15 scales, onto the scene as it is (:func:`frisicp_bench.sensor.sensed_crop_case`).

The sensor: Gaussian noise along the ray of 0.1 % of the scene's diagonal at the median range
(a Kinect v1 at 2 m: about 6 mm, a tenth of a per cent of a 6 m room's diagonal; ``--noise``
another share, e.g. a stereo camera's larger noise), and depth
steps of 0.5, 1 or 2 % of it there (``--steps``), both growing with the range squared. The
scenes: the development ones (rs1, the bunny, the dragon) and three held-out clouds (the chef
figure, the second dragon sampling, a real bunny scan); the method was never looked at on this
noise model. Each case is also registered from the truth (warm, before the cold retry:
``trustworthy.from_truth``): right and reliable there says the data determine the pose to the
tolerance. Scored like trustworthy.py: right = rotation < 1 deg, scale < 1 %, translation < 0.5 %
of the model's diagonal; what must be 0 is **wrong and reliable**.

The clouds are handed to ``register`` where the case puts them (the data moved by the truth's
inverse, the model in the scene's coordinates), where the core sees no depth steps about their
origins. ``--sensor-frames`` hands each cloud in its own camera's frame instead, as a driver
publishes it (the truth moved with them, :meth:`frisicp_bench.scenes.SceneCase.in_sensor_frames`):
there the core finds two frames' coarse steps and registers their averages over a step's voxels
(``frisicp_core.terraces``; after the cap, as in the node and ``frisicp bag`` by default). Each
case records the steps ``frisicp_core.find_depth_steps`` finds in each cloud about its camera, and
whether the core averaged them (the "averaged by the core" column).

``--occlusion``: each camera keeps only the points it sees (:func:`frisicp_bench.sensor.visible`,
a z-buffer), so two frames also differ in what each one's foreground hides.

``--flying``: with ``--occlusion``, every depth edge of the image (neighbouring pixels whose
fronts lie apart) also reports a flying pixel half-way between the two fronts
(``visible(..., flying=True)``), the mixed pixels of time-of-flight and structured-light cameras.

``--on-shells``: the noise before the quantisation, as in a camera, so every reported depth lies
exactly on a shell and the terraces are flat (by default the noise comes after it and blurs them).

``--rings N``: a spinning lidar's sampling instead of a camera's raster: N beams over the
view's elevations, each keeping a thin band of points (:func:`frisicp_bench.sensor.ring_sampled`),
so the clouds come as rings; with ``--steps 0`` its noise is along the rays only (a lidar's
ranges are not quantised in disparity).

``--ring-spacing DEG``: a real lidar's beams instead, at fixed elevations DEG apart about the
z axis (:func:`frisicp_bench.sensor.fixed_rings`), the same for both frames, and the second
frame's sensor moved across that axis (``sensed_frames_case(..., level=True)``), as a vehicle's
lidar moves: its rings on the ground and on walls along the way fall where the other frame's
did, the lidar's counterpart of terrace onto terrace.

``--average F``: what a user can do about coarse steps: both clouds averaged on a voxel grid
(:func:`frisicp_core.voxel_centroids`, the mean of each voxel's points, as the node's and
``frisicp bag``'s ``voxel_mode: centroid`` does) of edge F times the depth step at the median
range, in each cloud's own units (the sensor's step, known in its frame), before the cap. The
stream then tells the core not to average them again (``frisicp_ros.stream.depth_check``), as
the scene frames here do; with ``--sensor-frames`` the core averages the averages again.

Usage: python benchmarks/depth_sensor.py [--jobs 2] [--data DIR] [--steps 0.005,0.01,0.02]
                                         [--suite frames] [--occlusion [--flying]] [--on-shells]
                                         [--rings N | --ring-spacing DEG] [--sensor-frames]
                                         [--average F] [--draw N] [--out docs/depth_sensor.md]
       python benchmarks/depth_sensor.py --quick   # one frame pair and one crop of rs1 -> build/
Exits 0 without measuring when the data folder is absent, saying so.
"""

from __future__ import annotations

import os

os.environ.setdefault("OMP_NUM_THREADS", "1")  # before numpy and pykdtree load

import functools
import sys
import zlib
from pathlib import Path
from typing import Any

import numpy as np
from trustworthy import from_truth, pose_determined

from frisicp_bench import script
from frisicp_bench.cases import PAPER_SCALES
from frisicp_bench.metrics import model_size, pose_errors
from frisicp_bench.report import (
    case_record,
    three_sigma_bounds,
    within_three_sigma,
    write_report,
    wrong_but_reliable,
)
from frisicp_bench.scenes import object_cloud
from frisicp_bench.sensor import fixed_rings, ring_sampled, sensed_crop_case, sensed_frames_case, visible
from frisicp_core import downsample, register, voxel_centroids
from frisicp_core.depth_steps import find_depth_steps

TITLE = "Depth-sensor noise: frames and crops with errors along the rays and quantised depth"
SCENES = ("rs1.pcd", "bun_zipper.ply", "dragon1.xyz", "chef.pcd", "dragon2.xyz", "bunny_part2.xyz")
HELD_OUT = ("chef.pcd", "dragon2.xyz", "bunny_part2.xyz")
STEPS = (0.005, 0.01, 0.02)
NOISE = 0.001
SHIFTS = (0.1, 0.2, 0.3)
SHARES = (0.3, 0.45, 0.6)
REPEATS = 2
CAP = 10_000
SUITES = ("frames", "crop onto scene")


def score(
    key: tuple[str, str, float, float, int],
    data_dir: Path,
    draw: int,
    average: float = 0.0,
    occlusion: bool = False,
    rings: int = 0,
    flying: bool = False,
    on_shells: bool = False,
    sensor_frames: bool = False,
    ring_spacing: float = 0.0,
    noise: float = NOISE,
) -> dict[str, Any]:
    """Build, register (cold and from the truth) and score one case, deterministic in its key and
    ``draw``: (suite, scene, depth step, shift or share, repeat); ``occlusion``, ``flying``,
    ``on_shells``, ``rings``, ``ring_spacing`` (degrees), ``sensor_frames``, ``average`` and
    ``noise`` as the options of the same names (module doc)."""
    suite, scene_name, step, size, repeat = key
    salt = f"{suite}/{scene_name}/{step}/{size}/{repeat}" + (f"/draw {draw}" if draw else "")
    rng = np.random.default_rng(zlib.crc32(salt.encode()))
    sight = (
        functools.partial(
            _sight, occlusion=occlusion, rings=rings, flying=flying, ring_spacing=np.radians(ring_spacing)
        )
        if occlusion or rings or ring_spacing
        else None
    )
    scene = object_cloud(data_dir, scene_name)
    name = Path(scene_name).stem
    if suite == "frames":
        case = sensed_frames_case(
            scene, name, step, size, noise, rng, sight, on_shells, level=ring_spacing > 0
        )
    else:
        case = sensed_crop_case(
            scene, name, size, float(rng.choice(PAPER_SCALES)), step, noise, rng, sight, on_shells
        )
    if sensor_frames:
        case = case.in_sensor_frames()
    assert case.truth is not None
    data, model = case.data, case.model
    if average > 0:
        edge = average * step * model_size(scene)
        # The data are in the sensor's frame, scaled by the truth's inverse; the crops' model is
        # the scene as it is, not sensed, and is left alone.
        data = voxel_centroids(data, edge / case.truth.scale)
        if suite == "frames":
            model = voxel_centroids(model, edge)
    data, model = downsample(data, CAP, rng), downsample(model, CAP, rng)
    result = register(data, model)
    errors = pose_errors(result.similarity, case.truth, data, case.model_diagonal)
    warm = from_truth(data, model, case.truth)
    from_the_truth = pose_errors(warm.similarity, case.truth, data, case.model_diagonal)
    # What the node and frisicp bag see: each cloud in its sensor's frame, about the origin.
    found = [
        None if sensor is None else find_depth_steps(cloud - sensor)
        for cloud, sensor in zip((data, model), case.sensors, strict=True)
    ]
    return case_record(
        errors,
        result,
        suite=suite,
        scene=scene_name,
        step=step,
        case=case.name,
        reason=result.reason,
        data_depth_step=None if found[0] is None else found[0].share,
        model_depth_step=None if found[1] is None else found[1].share,
        averaged_by_core=result.depth_averaged is not None,
        three_sigma=three_sigma_bounds(result, case.model_diagonal),
        truth_start={"right": from_the_truth.success, "reliable": warm.reliable},
    )


def _sight(
    points: np.ndarray,
    camera: np.ndarray,
    occlusion: bool,
    rings: int,
    flying: bool,
    ring_spacing: float = 0.0,
) -> np.ndarray:
    """What the sensor at ``camera`` keeps: the front surface (``occlusion``, with ``flying``
    pixels), in rings (``rings`` spread over the view, or ``ring_spacing`` radians apart)."""
    kept = visible(points, camera, flying) if occlusion else points
    if ring_spacing:
        return fixed_rings(kept, camera, ring_spacing)
    return ring_sampled(kept, camera, rings) if rings else kept


def percent(step: float) -> str:
    """A depth step in per cent: one decimal, two where one would round it (1.25 %)."""
    one = f"{100 * step:.1f}"
    return one if abs(float(one) - 100 * step) < 1e-9 else f"{100 * step:.2f}"


def line(record: dict[str, Any]) -> str:
    verdict = "reliable" if record["reliable"] else record["reason"][:50]
    flag = "  WRONG AND RELIABLE" if record["reliable"] and not record["success"] else ""
    flag += " (averaged by the core)" if record["averaged_by_core"] else ""
    return (
        f"step {percent(record['step'])} % {record['suite']:15s} {record['case']:28s} "
        f"{'ok  ' if record['success'] else 'FAIL'} rot {record['rotation_deg']:6.2f} deg "
        f"scale {100 * record['scale_error']:6.2f} %  {verdict}{flag}"
    )


def table(records: list[dict[str, Any]]) -> tuple[list[str], list[list[object]]]:
    header = [
        "depth step",
        "suite",
        "clouds",
        "cases",
        "right",
        "success (right, reliable)",
        "**wrong and reliable**",
        "truth start right, reliable",
        "right, refused",
        "averaged by the core",
    ]
    rows: list[list[object]] = []
    for step in dict.fromkeys(r["step"] for r in records):
        for suite in SUITES:
            for clouds, held_out in (("development", False), ("held-out", True)):
                group = [
                    r
                    for r in records
                    if r["step"] == step and r["suite"] == suite and (r["scene"] in HELD_OUT) == held_out
                ]
                if not group:
                    continue
                rows.append(
                    [
                        f"{percent(step)} %",
                        suite,
                        clouds,
                        len(group),
                        sum(r["success"] for r in group),
                        sum(r["success"] and r["reliable"] for r in group),
                        f"**{wrong_but_reliable(group)}**",
                        sum(pose_determined(r) for r in group),
                        sum(r["success"] and not r["reliable"] for r in group),
                        sum(r["averaged_by_core"] for r in group),
                    ]
                )
    return header, rows


def summary(records: list[dict[str, Any]], draw: int) -> str:
    wrong = [r for r in records if r["reliable"] and not r["success"]]
    text = (
        f"**{len(wrong)} of {len(records)} results wrong and reliable**; {sum(r['success'] for r in records)} right, "
        f"{sum(r['success'] and r['reliable'] for r in records)} of them reliable"
        + (f" (draw {draw}: fresh cases)." if draw else ".")
    )
    averaged = [r for r in records if r["averaged_by_core"]]
    text += (
        f" The core averaged both clouds over their depth steps (`frisicp_core.terraces`) in"
        f" {len(averaged)} cases: {sum(r['success'] for r in averaged)} right,"
        f" {sum(r['success'] and r['reliable'] for r in averaged)} of them reliable,"
        f" {sum(r['reliable'] and not r['success'] for r in averaged)} wrong and reliable."
    )
    sized = [r for r in records if r["reliable"] and r["three_sigma"]]
    flags = [within_three_sigma(r) for r in sized]
    within = [sum(flag[k] for flag in flags) for k in range(3)]
    text += (
        f" Of the {len(sized)} reliable results, {within[0]}, {within[1]} and {within[2]} lie within"
        " their 3 sigma in rotation, scale and translation."
    )
    if wrong:
        text += " The wrong and reliable ones (3 sigma: rotation, scale, translation / diagonal):\n"
        for r in wrong:
            three = r["three_sigma"] or [float("nan")] * 3
            start = r["truth_start"]
            text += (
                f"\n- step {percent(r['step'])} %, {r['suite']}, {r['case']}: rotation {r['rotation_deg']:.2f} deg, "
                f"scale {100 * r['scale_error']:.2f} %, translation {100 * r['translation_error']:.2f} % off; "
                f"3 sigma {three[0]:.2f} deg, {100 * three[1]:.2f} %, {100 * three[2]:.2f} %; from the truth: "
                f"{'right' if start['right'] else 'wrong'}, {'reliable' if start['reliable'] else 'refused'}"
                + ("; averaged by the core" if r["averaged_by_core"] else "")
            )
    return text


def main(argv: list[str] | None = None) -> int:
    command = script.parser(__file__, __doc__, "one frame pair and one crop of rs1", data=True, report=True)
    command.add_argument("--jobs", type=int, default=2, help="worker processes (default 2)")
    command.add_argument("--draw", type=int, default=0, help="salt of every seed: fresh cases (default 0)")
    command.add_argument(
        "--steps",
        default=",".join(str(step) for step in STEPS),
        help="depth steps at the median range, shares of the scene's diagonal (default %(default)s)",
    )
    command.add_argument(
        "--suite",
        choices=SUITES,
        action="append",
        default=None,
        help="only this suite (repeatable; default both)",
    )
    command.add_argument(
        "--average",
        type=float,
        default=0.0,
        metavar="F",
        help="average both clouds on voxels of F depth steps first (default 0: off)",
    )
    command.add_argument("--occlusion", action="store_true", help="each camera keeps only what it sees")
    command.add_argument(
        "--sensor-frames",
        action="store_true",
        help="each cloud in its camera's frame, as a driver publishes it",
    )
    command.add_argument(
        "--flying", action="store_true", help="with --occlusion: flying pixels at depth edges"
    )
    command.add_argument(
        "--on-shells", action="store_true", help="the noise before the quantisation: depths exactly on shells"
    )
    command.add_argument(
        "--rings",
        type=int,
        default=0,
        metavar="N",
        help="a lidar's N rings instead of a raster (default 0: off)",
    )
    command.add_argument(
        "--ring-spacing",
        type=float,
        default=0.0,
        metavar="DEG",
        help="a lidar's rings at fixed elevations DEG apart, the frames' sensors moved level (default 0: off)",
    )
    command.add_argument(
        "--noise",
        type=float,
        default=NOISE,
        metavar="SHARE",
        help="noise along the rays at the median range, a share of the scene's diagonal (default %(default)s)",
    )
    args = script.parse(command, argv)
    if not (np.isfinite(args.noise) and 0.0 <= args.noise < 1.0):
        command.error("--noise must be a share of the diagonal in [0, 1)")
    if args.flying and not args.occlusion:
        command.error("--flying needs --occlusion (flying pixels lie at the edges it finds)")
    if args.rings < 0 or args.rings == 1:
        command.error("--rings must be 0 (off) or at least 2")
    if not (np.isfinite(args.ring_spacing) and 0.0 <= args.ring_spacing < 90.0):
        command.error("--ring-spacing must be a number of degrees in [0, 90)")
    if args.ring_spacing and args.rings:
        command.error("--rings and --ring-spacing are two lidars: choose one")
    if not (np.isfinite(args.average) and args.average >= 0):
        command.error("--average must be a finite number >= 0")
    suites = tuple(args.suite or SUITES)
    try:
        steps = tuple(float(word) for word in args.steps.split(","))
    except ValueError:
        command.error(f"--steps must be comma-separated numbers, not {args.steps!r}")
    if not all(0.0 <= step < 1.0 for step in steps):
        command.error("every --steps value must lie in [0, 1)")
    if args.quick:
        cases = [("frames", "rs1.pcd", steps[0], 0.2, 0), ("crop onto scene", "rs1.pcd", steps[0], 0.45, 0)]
    else:
        cases = [
            (suite, scene, step, size, repeat)
            for step in steps
            for scene in SCENES
            for suite, sizes in (("frames", SHIFTS), ("crop onto scene", SHARES))
            if suite in suites
            for size in sizes
            for repeat in range(REPEATS)
        ]
    work = functools.partial(
        score,
        data_dir=args.data,
        draw=args.draw,
        average=args.average,
        occlusion=args.occlusion,
        rings=args.rings,
        flying=args.flying,
        on_shells=args.on_shells,
        sensor_frames=args.sensor_frames,
        ring_spacing=args.ring_spacing,
        noise=args.noise,
    )
    records = script.map_cases(args, work, cases, line)
    if records is None:
        return 0
    title = (
        TITLE
        + (", each camera seeing only what is in front" if args.occlusion else "")
        + (", with flying pixels at depth edges" if args.flying else "")
        + (", depths exactly on the shells" if args.on_shells else "")
        + (f", in {args.rings} lidar rings" if args.rings else "")
        + (
            f", in lidar rings {args.ring_spacing:g} deg apart, the sensors moved level"
            if args.ring_spacing
            else ""
        )
        + (", each cloud in its camera's frame" if args.sensor_frames else "")
        + (f", averaged on voxels of {args.average:g} steps" if args.average else "")
        + (f", noise {100 * args.noise:g} % of the diagonal" if args.noise != NOISE else "")
    )
    write_report(
        args.out, title, script.command_line(args), summary(records, args.draw), table(records), records
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
