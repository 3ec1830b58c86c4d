"""Throughput of `frisicp bag`: pairs per second for --jobs 1 and 2, and time outside the core.

Writes a rosbag2 (mcap) with one 30,000-point model cloud and N data clouds of 30,000 points
(the model seen through a different similarity each time, 80 % of its points, light noise),
then times the real command end to end (process start, reading, conversion, registration,
JSONL and result bag writing) with --max-points 0 so every point is registered.

"Outside the core" is the wall time minus the time spent in ``frisicp_core.register`` (the
``seconds`` of each JSON line), relative to the wall time of --jobs 1.

    python benchmarks/bag_throughput.py                 # 200 pairs, the issue's setting
    python benchmarks/bag_throughput.py --pairs 20      # a quick look
    python benchmarks/bag_throughput.py --quick         # 2 pairs of 2,000-point clouds: a smoke run
"""

from __future__ import annotations

import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from rosbags.rosbag2 import StoragePlugin, Writer

from frisicp_bench import script
from frisicp_core import Similarity, axis_angle_rotation, bumpy_surface
from frisicp_ros.stream.outputs import rosbags_message_types
from frisicp_ros.stream.pointcloud2 import points_to_parts

MODEL_TOPIC, DATA_TOPIC = "/map", "/scan"
CLOUD_TYPE = "sensor_msgs/msg/PointCloud2"


def similarity(k: int, rng: np.random.Generator) -> Similarity:
    axis = rng.normal(size=3)
    rotation = axis_angle_rotation(axis, np.deg2rad(rng.uniform(5, 40)))
    return Similarity(rng.uniform(0.5, 2.0), rotation, rng.normal(size=3))


def write_bag(path: Path, pairs: int, points: int) -> None:
    rng = np.random.default_rng(0)
    types = rosbags_message_types()
    model = bumpy_surface(points, seed=0)
    with Writer(path, version=8, storage_plugin=StoragePlugin.MCAP) as writer:
        from rosbags.typesys import Stores, get_typestore

        typestore = get_typestore(Stores.ROS2_JAZZY)
        model_conn = writer.add_connection(MODEL_TOPIC, CLOUD_TYPE, typestore=typestore)
        data_conn = writer.add_connection(DATA_TOPIC, CLOUD_TYPE, typestore=typestore)

        def write(connection, cloud_points: np.ndarray, stamp_ns: int, frame: str) -> None:
            msg = types.point_cloud(points_to_parts(cloud_points), types.header(stamp_ns, frame))
            writer.write(connection, stamp_ns, typestore.serialize_cdr(msg, CLOUD_TYPE))

        write(model_conn, model, 10**9, "map")
        for k in range(pairs):
            truth = similarity(k, rng)
            sample = model[rng.permutation(points)[: int(0.8 * points)]]
            data = truth.inverse().apply(sample) + rng.normal(scale=0.002, size=sample.shape)
            # 30,000 points per data cloud too: the kept 80 % plus a resampled 20 %.
            extra = data[rng.integers(0, len(data), points - len(data))]
            write(data_conn, np.vstack([data, extra]), 2 * 10**9 + k * 10**8, "lidar")


def run(bag: Path, jobs: int, workdir: Path, env_extra: dict[str, str]) -> dict[str, float]:
    out, out_bag = workdir / f"jobs{jobs}.jsonl", workdir / f"out_jobs{jobs}_{time.monotonic_ns()}"
    command = [
        str(Path(sys.executable).parent / "frisicp"),
        "bag",
        str(bag),
        "--model-topic",
        MODEL_TOPIC,
        "--data-topic",
        DATA_TOPIC,
        "--max-points",
        "0",
        "--no-warm-start",  # independent pairs: the same work for --jobs 1 and 2 (no chunked warm start)
        "--jobs",
        str(jobs),
        "--out",
        str(out),
        "--out-bag",
        str(out_bag),
        "--no-progress",
    ]
    started = time.perf_counter()
    subprocess.run(command, check=True, env={**os.environ, **env_extra}, stderr=subprocess.DEVNULL)
    wall = time.perf_counter() - started
    load = os.getloadavg()[0]  # the last minute: other work on the machine skews the figures
    records = [json.loads(line) for line in out.read_text().splitlines()]
    core = sum(r["seconds"] for r in records)
    return {
        "jobs": jobs,
        "pairs": len(records),
        "wall_seconds": wall,
        "pairs_per_second": len(records) / wall,
        "core_seconds": core,
        "converged": sum(r["converged"] for r in records),
        "env": " ".join(f"{k}={v}" for k, v in env_extra.items()) or "default",
        "load_average_1min": load,
    }


def main(argv: list[str] | None = None) -> int:
    parser = script.parser(__file__, __doc__, "2 pairs of 2,000-point clouds", json_out=True)
    parser.add_argument("--pairs", type=int, default=200)
    parser.add_argument("--points", type=int, default=30000)
    args = script.parse(parser, argv)
    if args.quick:
        args.pairs, args.points = 2, 2000
    cores = str(os.cpu_count() or 2)
    with tempfile.TemporaryDirectory() as tmp:
        workdir = Path(tmp)
        bag = workdir / "input"
        write_bag(bag, args.pairs, args.points)
        runs = [
            run(bag, 1, workdir, {}),
            run(bag, 2, workdir, {}),
            # --jobs 1 with pykdtree's OpenMP on one thread, like each --jobs 2 worker
            run(bag, 1, workdir, {"OMP_NUM_THREADS": "1"}),
            # --jobs 2 without the bag mode's OMP_NUM_THREADS=1 per worker
            run(bag, 2, workdir, {"OMP_NUM_THREADS": cores}),
        ]
    single = runs[0]
    outside = 1 - single["core_seconds"] / single["wall_seconds"]
    print(f"machine: {platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}")
    print(f"bag: {args.pairs} pairs of {args.points}-point clouds (rosbag2, mcap)")
    for result in runs:
        print(
            f"--jobs {result['jobs']} ({result['env']}): {result['pairs_per_second']:.3f} pairs/s, "
            f"wall {result['wall_seconds']:.1f} s, core {result['core_seconds']:.1f} s, "
            f"converged {result['converged']}/{result['pairs']}, load average at the end {result['load_average_1min']:.1f}"
        )
    print(
        f"speed-up --jobs 2 / --jobs 1: {runs[1]['pairs_per_second'] / single['pairs_per_second']:.2f}x; "
        f"against --jobs 1 with OMP_NUM_THREADS=1: {runs[1]['pairs_per_second'] / runs[2]['pairs_per_second']:.2f}x; "
        f"--jobs 2 with {cores} OMP threads per worker: {runs[3]['pairs_per_second'] / single['pairs_per_second']:.2f}x"
    )
    print(f"time outside frisicp_core.register at --jobs 1: {100 * outside:.1f} %")
    script.write_json(args.json, {"runs": runs, "outside_core_share": outside})
    return 0


if __name__ == "__main__":
    sys.exit(main())
