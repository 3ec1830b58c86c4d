"""Latency, throughput and resource use of register_node under a 10 Hz stream of large clouds.

    .venv/bin/python benchmarks/node_latency.py                  # 60 s, 100k-point clouds, 10 Hz
    .venv/bin/python benchmarks/node_latency.py --duration 300   # the 5-minute growth check

Starts ``register_node`` (its console script, own process, loopback DDS in its own domain),
publishes a latched 100,000-point model and 100,000-point data clouds (x y z + intensity) at
``--rate`` Hz, and reports:

- latency from data-cloud receipt to ~/transform publication (the node's own measurement,
  reported in /diagnostics) and end to end (publish -> ~/transform received here);
- achieved output rate, pairs dropped by the newest-wins slot;
- node overhead (PointCloud2 conversion + output building/publication) / core registration time;
- the node's resident memory over the run (growth = leak or queue growth).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np

DOMAIN_ID = 188  # own domain: never shared with a test module or the demo


def parse_args() -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=60.0, help="seconds of streaming (default 60)")
    parser.add_argument("--rate", type=float, default=10.0, help="data clouds per second (default 10)")
    parser.add_argument("--points", type=int, default=100_000, help="points per data cloud")
    parser.add_argument("--model-points", type=int, default=100_000, help="points in the model cloud")
    parser.add_argument(
        "--max-points", type=int, default=20_000, help="node parameter max_points (0 = no cap)"
    )
    parser.add_argument(
        "--data-qos",
        choices=("reliable", "sensor_data"),
        default="reliable",
        help="QoS of the data stream (publisher and the node's data_qos). Fast DDS loses"
        " most 1.6 MB best-effort messages over loopback: see docs/node.md",
    )
    parser.add_argument("--json", type=Path, help="also write the figures here")
    return parser.parse_args()


def rss_kib(pid: int) -> int:
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1])
    return 0


def main() -> int:
    args = parse_args()
    os.environ.update(ROS_DOMAIN_ID=str(DOMAIN_ID), ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST")
    os.environ.pop("ROS_STATIC_PEERS", None)
    import rclpy
    from diagnostic_msgs.msg import DiagnosticArray
    from geometry_msgs.msg import TransformStamped
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy, qos_profile_sensor_data
    from sensor_msgs.msg import PointCloud2

    from frisicp_core import Similarity, bumpy_surface
    from frisicp_ros.node.demo import stop_node
    from frisicp_ros.stream.outputs import rclpy_message_types
    from frisicp_ros.stream.pointcloud2 import points_to_parts

    node = subprocess.Popen(
        [
            str(Path(sys.executable).parent / "register_node"),
            "--ros-args",
            "-r",
            "model:=/bench/model",
            "-r",
            "data:=/bench/data",
            "-p",
            "model_qos:=transient_local",
            "-p",
            f"max_points:={args.max_points}",
            "-p",
            f"data_qos:={args.data_qos}",
        ],
        env=dict(os.environ),
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
    )

    types = rclpy_message_types()
    truth = Similarity(
        1.3, np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]), np.array([1.0, 2.0, 0.5])
    )
    model = types.point_cloud(
        points_to_parts(bumpy_surface(args.model_points, seed=0)), types.header(0, "map")
    )
    rng = np.random.default_rng(1)
    data_clouds = []  # built before the clock starts: the publisher must keep up with --rate
    for seed in range(5):
        points = truth.inverse().apply(bumpy_surface(args.points, seed=seed + 1))
        points += rng.normal(scale=0.002, size=points.shape)
        parts = points_to_parts(points, {"intensity": rng.random(args.points).astype(np.float32)})
        data_clouds.append(types.point_cloud(parts, types.header(0, "lidar")))

    context = rclpy.Context()
    rclpy.init(context=context)
    bench = rclpy.create_node("latency_bench", context=context)
    latched = QoSProfile(
        depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL
    )
    model_pub = bench.create_publisher(PointCloud2, "/bench/model", latched)
    data_qos = (
        qos_profile_sensor_data
        if args.data_qos == "sensor_data"
        else QoSProfile(depth=5, reliability=ReliabilityPolicy.RELIABLE)
    )
    data_pub = bench.create_publisher(PointCloud2, "/bench/data", data_qos)
    sent_at: dict[int, float] = {}
    end_to_end: list[float] = []
    outputs: list[float] = []
    diagnostics: list[dict[str, str]] = []
    lock = threading.Lock()

    def on_transform(msg: TransformStamped) -> None:
        stamp = msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec
        now = time.monotonic()
        with lock:
            outputs.append(now)
            if stamp in sent_at:
                end_to_end.append(now - sent_at.pop(stamp))

    def on_diagnostics(msg: DiagnosticArray) -> None:
        for status in msg.status:
            if status.name.startswith("frisicp"):
                diagnostics.append({kv.key: kv.value for kv in status.values})

    bench.create_subscription(TransformStamped, "/frisicp/transform", on_transform, 10)
    bench.create_subscription(DiagnosticArray, "/diagnostics", on_diagnostics, 10)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(bench)
    spinner = threading.Thread(target=executor.spin, daemon=True)
    spinner.start()
    model_pub.publish(model)

    # Warm-up: wait for the first answer (node start, discovery, first cold registration).
    deadline = time.monotonic() + 60
    while not outputs and time.monotonic() < deadline and node.poll() is None:
        msg = data_clouds[0]
        msg.header.stamp = bench.get_clock().now().to_msg()
        with lock:
            sent_at[msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec] = time.monotonic()
        data_pub.publish(msg)
        time.sleep(1.0)
    if not outputs:
        print("register_node never answered:", node.stderr.read() if node.poll() is not None else "")
        return 1
    time.sleep(3.0)
    with lock:
        end_to_end.clear()
        outputs.clear()
        sent_at.clear()
    diagnostics.clear()

    memory: list[tuple[float, int]] = []
    start = time.monotonic()
    sent = 0
    next_sample = start
    while (now := time.monotonic()) - start < args.duration:
        msg = data_clouds[sent % len(data_clouds)]
        msg.header.stamp = bench.get_clock().now().to_msg()
        with lock:
            sent_at[msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec] = now
        data_pub.publish(msg)
        sent += 1
        if now >= next_sample:
            memory.append((now - start, rss_kib(node.pid)))
            next_sample += max(args.duration / 30, 1.0)
        time.sleep(max(0.0, start + sent / args.rate - time.monotonic()))
    elapsed = time.monotonic() - start
    time.sleep(3.0)  # the last answers and one more diagnostics message
    memory.append((time.monotonic() - start, rss_kib(node.pid)))

    node_log = stop_node(node, timeout=30)
    executor.shutdown(timeout_sec=5)
    spinner.join(timeout=5)  # a spin still inside rcl at interpreter exit aborts the process
    bench.destroy_node()
    rclpy.shutdown(context=context)

    last = diagnostics[-1] if diagnostics else {}
    first_dropped = int(diagnostics[0].get("dropped pairs", 0)) if diagnostics else 0
    with lock:
        e2e = np.array(end_to_end) * 1e3
        answered = len(outputs)
    quarter = max(len(memory) // 4, 1)
    figures = {
        "duration_s": round(elapsed, 1),
        "data_qos": args.data_qos,
        "data_points": args.points,
        "model_points": args.model_points,
        "max_points": args.max_points,
        "input_rate_hz": round(sent / elapsed, 2),
        "received_by_node_hz": round(
            float(np.mean([float(d.get("data rate (Hz)", "nan")) for d in diagnostics])), 2
        )
        if diagnostics
        else None,
        "output_rate_hz": round(answered / elapsed, 2),
        "dropped_pairs": int(last.get("dropped pairs", 0)) - first_dropped,
        "node_latency_p50_ms": float(last.get("latency p50 (ms)", "nan")),
        "node_latency_p95_ms": float(last.get("latency p95 (ms)", "nan")),
        "end_to_end_p50_ms": round(float(np.percentile(e2e, 50)), 1) if e2e.size else None,
        "end_to_end_p95_ms": round(float(np.percentile(e2e, 95)), 1) if e2e.size else None,
        "registration_mean_ms": float(last.get("registration mean (ms)", "nan")),
        "node_overhead_mean_ms": float(last.get("node overhead mean (ms)", "nan")),
        "overhead_fraction": float(last.get("node overhead / registration", "nan")),
        "rss_first_quarter_mib": round(float(np.mean([kib for _, kib in memory[:quarter]])) / 1024, 1),
        "rss_last_quarter_mib": round(float(np.mean([kib for _, kib in memory[-quarter:]])) / 1024, 1),
        "rss_max_mib": round(max(kib for _, kib in memory) / 1024, 1),
        "rss_series_mib": [(round(t), round(kib / 1024, 1)) for t, kib in memory],
        "node_exit_code": node.returncode,
        "node_traceback": "Traceback" in node_log,
    }
    width = max(map(len, figures))
    for key, value in figures.items():
        print(f"{key:<{width}}  {value}")
    if args.json:
        args.json.write_text(json.dumps(figures, indent=2) + "\n")
    return 0 if node.returncode == 0 and not figures["node_traceback"] else 1


if __name__ == "__main__":
    sys.exit(main())
