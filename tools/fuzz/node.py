"""Hostile PointCloud2 messages and parameter attacks to a running ``register_node`` (the console
script, a process of its own), over DDS on loopback in a domain of its own.

Checks: the node's process is alive at the end and printed no traceback; every valid pair sent
between the hostile messages is answered, correctly (rotation < 1 degree, scale < 1 %); no pose
is published for a cloud of nonsense numbers (as data or as model); every parameter attack is
answered (accepted or refused with a reason) and the node answers valid pairs after each batch;
its resident memory grows by less than 30 MiB after warm-up.
"""

from __future__ import annotations

import copy
import os
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np
from common import BIN, Tally

from frisicp_core import Similarity, rotation_angle
from frisicp_ros.stream.settings import OPTIONS, Surface

# The hostile classes of the node's fuzz test (test/support/hostile_clouds.py), one set for both.
sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "test"))
from support.hostile_clouds import GARBAGE, HOSTILE, VALID_SHAPE, valid_data, valid_truth
from support.ros import cloud_message

DOMAIN = 171
NODE = "frisicp"


def environment() -> dict[str, str]:
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    os.environ.pop("ROS_STATIC_PEERS", None)
    return {**os.environ, "ROS_DOMAIN_ID": str(DOMAIN)}


HOSTILE_VALUES: list[Any] = [
    float("nan"), float("inf"), -float("inf"), -1, -1.0, 0, 0.0, 1e-300, 1e308, 2**62, -(2**62),
    "", "x" * 5000, "ä" * 300, "a b", "map\n", True, False, [1, 2], [0.5], ["a"],
]  # fmt: skip
NODE_OPTIONS = [option for option in OPTIONS if option.surfaces & Surface.NODE]


class Probe:
    """rclpy in this process: publishes clouds, hears the node's transforms, sets its parameters."""

    def __init__(self) -> None:
        import rclpy
        from geometry_msgs.msg import TransformStamped, Vector3Stamped
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.parameter_client import AsyncParameterClient
        from rclpy.qos import QoSProfile, ReliabilityPolicy
        from sensor_msgs.msg import PointCloud2

        reliable = QoSProfile(depth=50, reliability=ReliabilityPolicy.RELIABLE)
        self.context = rclpy.Context()
        rclpy.init(context=self.context, domain_id=DOMAIN)
        self.node = rclpy.create_node("fuzz_probe", context=self.context)
        self.model = self.node.create_publisher(PointCloud2, "model", reliable)
        self.data = self.node.create_publisher(PointCloud2, "data", reliable)
        self.lock = threading.Lock()
        self.transforms: dict[tuple[int, int], Any] = {}
        self.scales: dict[tuple[int, int], float] = {}
        self._last_transform: tuple[int, int] | None = None
        self.node.create_subscription(TransformStamped, f"/{NODE}/transform", self._on_transform, reliable)
        self.node.create_subscription(Vector3Stamped, f"/{NODE}/scale", self._on_scale, reliable)
        self.parameters = AsyncParameterClient(self.node, NODE)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.spinner = threading.Thread(target=self.executor.spin, daemon=True)
        self.spinner.start()

    def _on_transform(self, message: Any) -> None:
        with self.lock:
            key = (message.header.stamp.sec, message.header.stamp.nanosec)
            self.transforms[key] = message
            self._last_transform = key

    def _on_scale(self, message: Any) -> None:  # published right after its transform
        with self.lock:
            if self._last_transform is not None:
                self.scales[self._last_transform] = message.vector.x  # s (y, z: its sigma)

    def answer(self, stamp: tuple[int, int], timeout: float) -> Similarity | None:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            with self.lock:
                if stamp in self.transforms and stamp in self.scales:
                    t, q = (
                        self.transforms[stamp].transform.translation,
                        self.transforms[stamp].transform.rotation,
                    )
                    return Similarity.from_quaternion(
                        self.scales[stamp], [q.x, q.y, q.z, q.w], [t.x, t.y, t.z]
                    )
            time.sleep(0.002)
        return None

    def set_parameter(self, name: str, value: Any, timeout: float = 10.0) -> Any:
        from rclpy.parameter import Parameter

        future = self.parameters.set_parameters([Parameter(name, value=value)])
        deadline = time.monotonic() + timeout
        while not future.done() and time.monotonic() < deadline:
            time.sleep(0.002)
        return future.result() if future.done() else None

    def close(self) -> None:
        import rclpy

        self.executor.shutdown(timeout_sec=5)
        self.node.destroy_node()
        rclpy.shutdown(context=self.context)
        self.spinner.join(5)


def rss_mib(pid: int) -> float:
    with open(f"/proc/{pid}/status") as status:
        return next(int(line.split()[1]) for line in status if line.startswith("VmRSS:")) / 1024.0


def campaign(rng: np.random.Generator, messages: int, attacks: int, deadline: float) -> tuple[Tally, Tally]:
    env = environment()
    node = subprocess.Popen(
        [str(BIN / "register_node"), "--ros-args", "-p", "model_qos:=reliable", "-p", "data_qos:=reliable",
         "-p", "max_points:=0", "-p", "diagnostics_period:=60.0"],
        env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, errors="replace",
        start_new_session=True,
    )  # fmt: skip
    probe = Probe()
    clouds, parameters = (
        Tally("register_node, hostile PointCloud2"),
        Tally("register_node, parameter attacks"),
    )
    try:
        while probe.data.get_subscription_count() == 0 or probe.parameters.services_are_ready() is False:
            if time.monotonic() > deadline or node.poll() is not None:
                break
            probe.parameters.wait_for_services(0.1)
        _messages(probe, node.pid, clouds, rng, messages, deadline)
        _parameters(probe, parameters, rng, attacks, deadline)
    finally:
        probe.close()
        alive = node.poll() is None
        node.terminate()
        try:
            _, err = node.communicate(timeout=20)
        except subprocess.TimeoutExpired:
            node.kill()
            _, err = node.communicate()
            clouds.problem("hangs", "register_node did not end within 20 s of SIGTERM")
        if not alive:
            clouds.problem("crashes", f"register_node ended during the campaign: exit {node.returncode}")
        if "Traceback (most recent call last)" in err:
            clouds.problem("tracebacks", err[err.index("Traceback") :][:300])
        clouds.exits["register_node on SIGTERM"] = node.returncode
    return clouds, parameters


def _messages(
    probe: Probe, pid: int, tally: Tally, rng: np.random.Generator, count: int, deadline: float
) -> None:
    classes = sorted(HOSTILE)
    stamp = 1_800_000_000_000_000_000
    valid, garbage_stamps, rss_start = 0, set(), None
    while tally.tried < count and time.monotonic() < deadline:
        # a valid pair: its model, then its data; the answer must be right
        pose = valid_truth(valid)
        stamp += 10_000_000
        probe.model.publish(cloud_message(pose.apply(VALID_SHAPE), "map", stamp))
        time.sleep(0.02)
        stamp += 10_000_000
        data = valid_data(rng, stamp)
        probe.data.publish(data)
        valid += 1
        estimate = probe.answer((data.header.stamp.sec, data.header.stamp.nanosec), timeout=10.0)
        if estimate is None:
            tally.problem("lost_results", f"valid pair {valid}: no answer within 10 s")
        elif (
            np.degrees(rotation_angle(estimate.rotation.T @ pose.rotation)) >= 1.0
            or abs(estimate.scale / pose.scale - 1) >= 0.01
        ):
            tally.problem("wrong_answers", f"valid pair {valid}: answered wrongly")
        for _ in range(8):  # hostile messages, every class in turn
            name = classes[tally.tried % len(classes)]
            stamp += 10_000_000
            message = HOSTILE[name](rng, stamp)
            if rng.random() < 0.25:  # as the model of the next data cloud
                probe.model.publish(message)
                time.sleep(0.005)
                stamp += 10_000_000
                message = valid_data(rng, stamp)
            probe.data.publish(copy.copy(message))
            if name in GARBAGE:
                garbage_stamps.add((message.header.stamp.sec, message.header.stamp.nanosec))
            tally.tried += 1
            tally.notes[name] += 0  # every class appears in the notes, counted below
            time.sleep(0.01)
        if rss_start is None and tally.tried >= count // 10:
            rss_start = rss_mib(pid)
    time.sleep(1.0)  # outputs in flight
    with probe.lock:
        published = garbage_stamps & set(probe.transforms)
    for stamp_key in sorted(published):
        tally.problem(
            "wrong_answers", f"a cloud of nonsense numbers was published as a pose (stamp {stamp_key})"
        )
    tally.notes.clear()
    tally.notes["valid pairs"] = valid
    tally.notes["classes"] = len(classes)
    tally.notes["garbage clouds"] = len(garbage_stamps)
    growth = rss_mib(pid) - (rss_start or rss_mib(pid))
    tally.notes["RSS growth (MiB, rounded)"] = round(growth)
    if growth > 30:
        tally.problem("crashes", f"resident memory grew {growth:.0f} MiB")


def _parameters(probe: Probe, tally: Tally, rng: np.random.Generator, count: int, deadline: float) -> None:
    defaults = {option.name: option.default for option in NODE_OPTIONS if not option.read_only}
    accepted = refused = 0
    valid = 1000
    while tally.tried < count and time.monotonic() < deadline:
        for _ in range(20):
            option = NODE_OPTIONS[int(rng.integers(len(NODE_OPTIONS)))]
            value = HOSTILE_VALUES[int(rng.integers(len(HOSTILE_VALUES)))]
            response = probe.set_parameter(option.name, value)
            tally.tried += 1
            if response is None:
                tally.problem("hangs", f"set {option.name} = {value!r:.40}: no answer within 10 s")
                return
            result = response.results[0]
            if result.successful:
                accepted += 1
            elif result.reason:
                refused += 1
            else:
                tally.problem("crashes", f"set {option.name} = {value!r:.40}: refused without a reason")
        for name, value in defaults.items():  # back to the defaults: each must be accepted
            response = probe.set_parameter(name, value)
            if response is None or not response.results[0].successful:
                tally.problem("crashes", f"restoring {name} = {value!r} failed")
        pose = valid_truth(valid)
        stamp = 1_900_000_000_000_000_000 + valid * 20_000_000
        probe.model.publish(cloud_message(pose.apply(VALID_SHAPE), "map", stamp))
        time.sleep(0.02)
        data = valid_data(rng, stamp + 10_000_000)
        probe.data.publish(data)
        valid += 1
        estimate = probe.answer((data.header.stamp.sec, data.header.stamp.nanosec), timeout=10.0)
        if estimate is None or abs(estimate.scale / pose.scale - 1) >= 0.01:
            tally.problem(
                "lost_results", f"after {tally.tried} attacks: the valid pair was not answered right"
            )
    tally.notes["accepted"] = accepted
    tally.notes["refused with a reason"] = refused
