"""The pictures in README and docs/node.md, made the way a user makes them (docs/images/).

- ``register_bunny.png``: ``frisicp register --plot`` of the Stanford bunny's scan bun090, scaled
  by 0.5, turned 25 degrees and shifted, onto the reconstruction bun_zipper_res2 (../shared/data;
  skipped with a note when absent);
- ``bag_over_time.png``: ``frisicp bag --plot`` of a 30 s recording made here: a latched map (the
  built-in bumpy surface) and a 2 Hz sensor moving as frisicp-demo's truth moves, with two
  damaged clouds (random bytes, a cloud of 3 points) among them;
- ``demo_last_alignment.png``: ``frisicp-demo --plot`` (ROS 2 on loopback, domain 187; skipped
  with a note without rclpy).

    python benchmarks/doc_pictures.py [--out docs/images] [--only register,bag,demo] [--data DIR]
    python benchmarks/doc_pictures.py --quick   # all three into build/doc_pictures: a 10 s recording, a 3 s demo
"""

from __future__ import annotations

import argparse
import importlib.util
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

from frisicp_bench import script
from frisicp_core import Similarity, axis_angle_rotation, bumpy_surface, read_points

ROOT = Path(__file__).resolve().parents[1]
SCRIPTS = Path(sys.executable).parent
DEMO_DOMAIN = "187"  # its own: never shared with node_latency.py (188), big_map_node.py (189) or a test
DEMO_SECONDS = 6  # the full run's demo; --quick: QUICK_DEMO_SECONDS
QUICK_DEMO_SECONDS = 3
CLOUDS = 60  # the bag picture's recording, 30 s at 2 Hz; --quick: QUICK_CLOUDS (10 s)
QUICK_CLOUDS = 20


def register_picture(args: argparse.Namespace) -> None:
    bunny = args.data / "bunny"
    if not (bunny / "bun090.ply").exists():
        script.skip(args, f"register picture: {bunny / 'bun090.ply'} is missing")
        return
    out = args.out
    truth = Similarity(0.5, axis_angle_rotation([0.2, 1.0, 0.1], np.deg2rad(25.0)), [0.03, -0.02, 0.01])
    with tempfile.TemporaryDirectory() as tmp:
        data = Path(tmp) / "bun090_moved.npy"
        np.save(data, truth.inverse().apply(read_points(bunny / "bun090.ply")))
        command = [str(SCRIPTS / "frisicp"), "register", str(data), str(bunny / "bun_zipper_res2.ply")]
        subprocess.run([*command, "--plot", str(out / "register_bunny.png")], check=True)


def recording(path: Path, clouds: int) -> None:
    """A rosbag2 (mcap) of a map and a moving sensor's ``clouds`` (2 Hz), two of them damaged, at
    about a third and two thirds of the way."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    from frisicp_ros.node.demo import truth_at
    from frisicp_ros.stream.outputs import rosbags_message_types
    from frisicp_ros.stream.pointcloud2 import points_to_parts

    typestore = get_typestore(Stores.ROS2_JAZZY)
    types = rosbags_message_types(typestore)
    rng = np.random.default_rng(3)
    start = 1_700_000_000_000_000_000
    with Writer(path, version=8, storage_plugin=StoragePlugin.MCAP) as writer:
        topics = {
            name: writer.add_connection(name, "sensor_msgs/msg/PointCloud2", typestore=typestore)
            for name in ("/map_cloud", "/points")
        }

        def write(topic: str, points: np.ndarray, frame: str, stamp: int) -> None:
            msg = types.point_cloud(points_to_parts(points), types.header(stamp, frame))
            writer.write(topics[topic], stamp, typestore.serialize_cdr(msg, "sensor_msgs/msg/PointCloud2"))

        write("/map_cloud", bumpy_surface(20000, seed=0), "map", start)
        for k in range(clouds):
            t, stamp = 0.5 * k, start + (k + 1) * 500_000_000
            if k == clouds * 7 // 20:
                points = rng.uniform(-1e3, 1e3, size=(3000, 3))  # random numbers, not a scene
            elif k == clouds * 7 // 10:
                points = rng.normal(size=(3, 3))  # too few points
            else:
                sample = bumpy_surface(3000, seed=int(rng.integers(1 << 30)))
                points = truth_at(t).inverse().apply(sample) + rng.normal(scale=0.005, size=sample.shape)
            write("/points", points, "sensor", stamp)


def bag_picture(args: argparse.Namespace) -> None:
    out = args.out
    with tempfile.TemporaryDirectory() as tmp:
        bag = Path(tmp) / "recording"
        recording(bag, QUICK_CLOUDS if args.quick else CLOUDS)
        subprocess.run(
            [
                str(SCRIPTS / "frisicp"),
                "bag",
                str(bag),
                "--model-topic",
                "/map_cloud",
                "--data-topic",
                "/points",
                "--no-progress",
                "--out",
                str(Path(tmp) / "results.jsonl"),
                "--plot",
                str(out / "bag_over_time.png"),
            ],
            check=True,
        )


def demo_picture(args: argparse.Namespace) -> None:
    if importlib.util.find_spec("rclpy") is None:
        script.skip(args, "demo picture: ROS 2 (rclpy) is not installed")
        return
    env = dict(os.environ, ROS_DOMAIN_ID=DEMO_DOMAIN, ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST")
    seconds = QUICK_DEMO_SECONDS if args.quick else DEMO_SECONDS
    command = [str(SCRIPTS / "frisicp-demo"), "--duration", str(seconds)]
    subprocess.run([*command, "--plot", str(args.out / "demo_last_alignment.png")], check=True, env=env)


PICTURES = {"register": register_picture, "bag": bag_picture, "demo": demo_picture}


def main() -> int:
    parser = script.parser(
        __file__,
        __doc__,
        "all three pictures into build/doc_pictures/, a 10 s recording, the demo for 3 s",
        data=True,
    )
    parser.add_argument(
        "--out",
        type=Path,
        default=None,
        help="the folder (default docs/images; build/doc_pictures with --quick)",
    )
    parser.add_argument("--only", default=",".join(PICTURES), help="comma-separated: " + ", ".join(PICTURES))
    args = script.parse(parser)
    args.out = args.out or ROOT / ("build/doc_pictures" if args.quick else "docs/images")
    args.out.mkdir(parents=True, exist_ok=True)
    for name in args.only.split(","):
        PICTURES[name](args)
    for picture in sorted(args.out.glob("*.png")):
        print(f"{picture}: {picture.stat().st_size / 1000:.0f} kB")
    return 0


if __name__ == "__main__":
    sys.exit(main())
