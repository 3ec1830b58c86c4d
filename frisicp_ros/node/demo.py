"""``frisicp-demo`` (``make demo``): the live node on a built-in shape, estimates vs truth.

Starts ``register_node`` as its own process (as ``ros2 run`` would), publishes the built-in
bumpy surface once as a latched model and, a few times per second, a scaled, rotated, shifted,
noisy copy as the data stream whose true similarity keeps changing; prints the node's estimate
next to the truth and draws its last alignment into a PNG (``--plot``). DDS stays on loopback,
in the ROS_DOMAIN_ID the user set (else its own, 142), so nothing leaves this machine.

``register_node`` is looked up beside this script first: ``ros2 run frisicp_ros frisicp-demo``
runs it from a workspace's ``lib/frisicp_ros``, where colcon installs both.
"""

from __future__ import annotations

import argparse
import os
import shutil
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from frisicp_core import Similarity, axis_angle_rotation, bumpy_surface, rotation_angle

DEFAULT_DOMAIN_ID = 142
STARTUP_TIMEOUT = 30.0  # s for the node to start and answer the first cloud
DRAIN_SECONDS = 3.0  # s to wait for the last answer after the stream stops
_KEPT_CLOUDS = 20  # data clouds kept for the picture of the last answered one


@dataclass(frozen=True)
class Estimate:
    similarity: Similarity
    received_at: float


def truth_at(t: float) -> Similarity:
    """A slowly changing similarity: scale 0.7..1.3, rotation about a wandering axis, a circling shift."""
    rotation = axis_angle_rotation([np.sin(0.2 * t), 1.0, 0.3], np.deg2rad(25.0 * np.sin(0.4 * t)))
    return Similarity(
        1.0 + 0.3 * np.sin(0.5 * t), rotation, np.array([0.5 * np.cos(0.3 * t), 0.5 * np.sin(0.3 * t), 0.2])
    )


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(prog="frisicp-demo", description=__doc__.splitlines()[0])
    parser.add_argument(
        "--duration", type=float, default=8.0, help="seconds of streaming after the first answer (default 8)"
    )
    parser.add_argument("--rate", type=float, default=2.0, help="data clouds per second (default 2)")
    parser.add_argument("--points", type=int, default=5000, help="points per data cloud (default 5000)")
    parser.add_argument("--noise", type=float, default=0.005, help="Gaussian noise sigma (default 0.005)")
    parser.add_argument(
        "--max-points",
        type=int,
        default=2500,
        help="node's max_points: the cap that bounds latency (default 2500)",
    )
    parser.add_argument(
        "--domain-id",
        type=int,
        default=None,
        help=f"ROS_DOMAIN_ID of the demo (default: the environment's ROS_DOMAIN_ID, else {DEFAULT_DOMAIN_ID})",
    )
    parser.add_argument(
        "--plot",
        default="frisicp_demo.png",
        metavar="PNG",
        help="draw the last alignment (data and model before and after) into this PNG (default"
        " %(default)s); empty: no picture",
    )
    return parser.parse_args(argv)


def domain_id(given: int | None, environ: dict[str, str] | os._Environ[str]) -> int:
    """The domain: ``--domain-id``, else a ROS_DOMAIN_ID the user set, else the demo's own."""
    if given is not None:
        return given
    value = environ.get("ROS_DOMAIN_ID", "").strip()
    return int(value) if value.isdigit() else DEFAULT_DOMAIN_ID


def isolate_dds(domain_id: int) -> dict[str, str]:
    """Loopback-only discovery in ``domain_id`` (set before rclpy is imported)."""
    os.environ["ROS_DOMAIN_ID"] = str(domain_id)
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    os.environ.pop("ROS_STATIC_PEERS", None)
    return dict(os.environ)


def register_node_script() -> str:
    """register_node beside this script (a colcon workspace's lib/frisicp_ros, a venv's bin), beside
    the interpreter, on PATH, or in an install prefix on AMENT_PREFIX_PATH."""
    places = [Path(sys.argv[0]).resolve().parent, Path(sys.executable).parent]
    places += [
        Path(prefix) / "lib" / "frisicp_ros"
        for prefix in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep)
        if prefix
    ]
    for place in places:
        if os.access(place / "register_node", os.X_OK):
            return str(place / "register_node")
    on_path = shutil.which("register_node")
    if on_path is None:
        looked = ", ".join(str(p) for p in places)
        raise SystemExit(
            f"frisicp-demo: register_node is not installed (looked in {looked} and PATH;"
            " pip install -e '.[ros]', or colcon build and source install/setup.bash)"
        )
    return on_path


def register_node_command(max_points: int) -> list[str]:
    script = register_node_script()
    return [
        script,
        "--ros-args",
        "-r",
        "model:=/frisicp_demo/model",
        "-r",
        "data:=/frisicp_demo/data",
        "-p",
        "model_qos:=transient_local",
        "-p",
        f"max_points:={max_points}",
        "-p",
        "data_frame:=demo_sensor",
    ]


def stop_node(node: subprocess.Popen, timeout: float) -> str:
    """SIGINT a node started with stderr=PIPE, as Ctrl-C would; kill it if it outlives ``timeout``.
    Returns what it wrote to stderr."""
    node.send_signal(signal.SIGINT)
    try:
        return node.communicate(timeout=timeout)[1]
    except subprocess.TimeoutExpired:
        node.kill()
        return node.communicate()[1]


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    args.domain_id = domain_id(args.domain_id, os.environ)
    env = isolate_dds(args.domain_id)
    node = subprocess.Popen(
        register_node_command(args.max_points),
        env=env,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
    )
    print(f"frisicp demo: register_node running (pid {node.pid}), ROS domain {args.domain_id}, loopback only")
    last: LastAlignment | None = None
    try:
        registered, sent, last = publish_demo_scans(args)
    except KeyboardInterrupt:
        registered, sent = [], 0
        print("\ninterrupted")
    finally:
        node_log = stop_node(node, timeout=20)
    clean = node.returncode == 0 and "Traceback" not in node_log
    print_summary(registered, sent, clean)
    if args.plot and last is not None:
        from frisicp_ros.stream.pictures import alignment_picture

        title = f"frisicp-demo: the node's last estimate (true scale {last.truth.scale:.3f})"
        print(
            f"last alignment drawn in {alignment_picture(last.data, last.model, last.estimate, args.plot, title)}"
        )
    if not clean:
        print(node_log, file=sys.stderr)
    return 0 if clean and registered else 1


@dataclass(frozen=True)
class LastAlignment:
    """The last answered data cloud, with the model, the node's estimate and the truth."""

    data: np.ndarray
    model: np.ndarray
    estimate: Similarity
    truth: Similarity


def publish_demo_scans(
    args: argparse.Namespace,
) -> tuple[list[tuple[Similarity, Similarity, float, float]], int, LastAlignment | None]:
    """Publish for ``args.duration`` s; return (truth, estimate, rms, latency) per answered cloud,
    the number sent, and the last answered cloud's alignment."""
    import rclpy
    from geometry_msgs.msg import TransformStamped, Vector3Stamped
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import PointCloud2

    from frisicp_ros.node.message_types import rclpy_message_types
    from frisicp_ros.stream.pointcloud2 import points_to_parts
    from frisicp_ros.stream.stamps import stamp_ns

    types = rclpy_message_types()
    context = rclpy.Context()
    rclpy.init(context=context, signal_handler_options=rclpy.SignalHandlerOptions.NO)
    publisher_node = rclpy.create_node("frisicp_demo_publisher", context=context)
    latched = QoSProfile(
        depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL
    )
    model_pub = publisher_node.create_publisher(PointCloud2, "/frisicp_demo/model", latched)
    data_pub = publisher_node.create_publisher(PointCloud2, "/frisicp_demo/data", 10)
    lock = threading.Lock()
    transforms: dict[int, TransformStamped] = {}
    arrival: dict[int, float] = {}
    scales: list[float] = []
    rms: list[float] = []

    def on_transform(msg: TransformStamped) -> None:
        stamp = stamp_ns(msg)
        with lock:
            transforms[stamp], arrival[stamp] = msg, time.monotonic()

    # scale and rms arrive in the same order as the transforms (same publisher thread, one each)
    publisher_node.create_subscription(TransformStamped, "/frisicp/transform", on_transform, 10)

    def collect(values: list[float]) -> Callable[[Vector3Stamped], None]:
        return lambda msg: values.append(msg.vector.x)

    publisher_node.create_subscription(Vector3Stamped, "/frisicp/scale", collect(scales), 10)
    publisher_node.create_subscription(Vector3Stamped, "/frisicp/rms", collect(rms), 10)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(publisher_node)
    spinner = threading.Thread(target=executor.spin, daemon=True)
    spinner.start()

    model_points = bumpy_surface(20000, seed=0)
    model_pub.publish(types.point_cloud(points_to_parts(model_points), types.header(0, "demo_map")))
    rng = np.random.default_rng(7)
    clouds: dict[int, np.ndarray] = {}
    sent: dict[int, tuple[Similarity, float]] = {}
    order: list[int] = []
    printed = 0
    print("model: bumpy surface, 20000 points, latched on /frisicp_demo/model (frame demo_map)")
    print(
        f"data:  {args.points} points at {args.rate:g} Hz, noise sigma {args.noise:g}, changing truth,"
        " on /frisicp_demo/data (frame demo_sensor)\n"
    )
    print("latency = data cloud published -> ~/transform received; rms in model units\n")
    print(
        f"{'t (s)':>6}  {'scale true':>10}  {'scale est':>10}  {'rot true':>8}  {'rot err':>8}"
        f"  {'trans err':>9}  {'rms':>8}  {'latency':>8}"
    )
    start = time.monotonic()
    next_send = start
    streaming_until: float | None = None  # set at the first answer: DDS discovery is not demo time
    try:
        while True:
            now = time.monotonic()
            if streaming_until is None and _answered(order, transforms, lock):
                streaming_until = now + args.duration
            if now - start > STARTUP_TIMEOUT and streaming_until is None:
                print(f"no answer from register_node within {STARTUP_TIMEOUT:.0f} s")
                break
            if streaming_until is not None and now >= streaming_until:
                # let the last cloud in flight come back, then stop
                if order[-1] in transforms or now >= streaming_until + DRAIN_SECONDS:
                    break
            elif now >= next_send:
                truth = truth_at(now - start)
                sample = bumpy_surface(args.points, seed=int(rng.integers(1 << 30)))
                data = truth.inverse().apply(sample) + rng.normal(scale=args.noise, size=sample.shape)
                stamp = int(time.time() * 1e9)
                data_pub.publish(types.point_cloud(points_to_parts(data), types.header(stamp, "demo_sensor")))
                sent[stamp] = (truth, now)
                order.append(stamp)
                clouds[stamp] = data
                for old in order[:-_KEPT_CLOUDS]:  # the last few, for the picture
                    clouds.pop(old, None)
                next_send += 1.0 / args.rate
            printed = print_new_rows(order, sent, transforms, arrival, scales, rms, lock, start, printed)
            time.sleep(0.01)
    finally:
        executor.shutdown(timeout_sec=5)
        spinner.join(timeout=5)  # a spin still inside rcl at interpreter exit aborts the process
        publisher_node.destroy_node()
        rclpy.shutdown(context=context)
    print_new_rows(order, sent, transforms, arrival, scales, rms, lock, start, printed)
    rows = _collect(order, sent, transforms, arrival, scales, rms, lock)
    answered = _answered(order, transforms, lock)[: len(rows)]
    last = None
    if rows and answered[-1] in clouds:
        truth, estimate, _, _ = rows[-1]
        last = LastAlignment(clouds[answered[-1]], model_points, estimate, truth)
    return rows, len(order), last


def _answered(order, transforms, lock) -> list[int]:
    with lock:
        return [stamp for stamp in order if stamp in transforms]


def _collect(order, sent, transforms, arrival, scales, rms, lock):
    rows = []
    for index, stamp in enumerate(_answered(order, transforms, lock)):
        if index >= len(scales) or index >= len(rms):
            break
        msg = transforms[stamp]
        q, t = msg.transform.rotation, msg.transform.translation
        estimate = Similarity.from_quaternion(scales[index], [q.x, q.y, q.z, q.w], [t.x, t.y, t.z])
        truth, sent_at = sent[stamp]
        rows.append((truth, estimate, rms[index], arrival[stamp] - sent_at))
    return rows


def print_new_rows(order, sent, transforms, arrival, scales, rms, lock, start, printed) -> int:
    rows = _collect(order, sent, transforms, arrival, scales, rms, lock)
    answered = _answered(order, transforms, lock)
    for (truth, estimate, error, latency), stamp in zip(rows[printed:], answered[printed:], strict=False):
        rot_err = np.degrees(rotation_angle(estimate.rotation.T @ truth.rotation))
        trans_err = np.linalg.norm(estimate.translation - truth.translation)
        print(
            f"{sent[stamp][1] - start:6.1f}  {truth.scale:10.4f}  {estimate.scale:10.4f}"
            f"  {np.degrees(truth.rotation_angle()):7.1f}°  {rot_err:7.3f}°  {trans_err:9.4f}"
            f"  {error:8.4f}  {latency * 1e3:6.0f} ms",
            flush=True,
        )
    return len(rows)


def print_summary(rows, sent: int, clean: bool) -> None:
    print()
    if rows:
        scale_err = np.median([abs(e.scale / t.scale - 1) for t, e, _, _ in rows]) * 100
        rot_err = np.median([np.degrees(rotation_angle(e.rotation.T @ t.rotation)) for t, e, _, _ in rows])
        trans_err = np.median([np.linalg.norm(e.translation - t.translation) for t, e, _, _ in rows])
        latency = np.median([lat for *_, lat in rows]) * 1e3
        print(
            f"registered {len(rows)} of {sent} data clouds (the rest were replaced by newer ones while"
            f" the node was busy); median errors: scale {scale_err:.3f} %, rotation {rot_err:.3f}°,"
            f" translation {trans_err:.4f}; median latency {latency:.0f} ms"
        )
    else:
        print(f"no estimate received for {sent} data clouds")
    print(
        "register_node stopped cleanly (SIGINT, exit code 0)"
        if clean
        else "register_node did NOT exit cleanly"
    )


if __name__ == "__main__":
    sys.exit(main())
