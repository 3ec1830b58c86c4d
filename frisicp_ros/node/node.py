"""``register_node``: the FRISICP ROS 2 node (thin glue around the shared pipeline).

Subscribes ``model`` and ``data`` (sensor_msgs/PointCloud2), pairs them (``pairing``), hands the
newest pair to one worker thread (registration never runs in an executor callback), and
publishes ``~/transform``, ``~/scale``, ``~/rms``, ``~/similarity``, ``~/aligned`` and
``/diagnostics``. See docs/node.md.
"""

from __future__ import annotations

import os

# One OpenMP thread for pykdtree unless the user chose otherwise: most queries are small, and on
# a 2-core machine the thread overhead made registration 1.3-1.5x slower (docs/node.md,
# docs/core_speed_omp1.md). It must be set before pykdtree loads, as libgomp reads it at load.
os.environ.setdefault("OMP_NUM_THREADS", "1")

import sys
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import rclpy
import rclpy.logging
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rcl_interfaces.msg import SetParametersResult
from rclpy.exceptions import ParameterException
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import (
    DurabilityPolicy,
    HistoryPolicy,
    QoSProfile,
    ReliabilityPolicy,
    qos_profile_sensor_data,
)
from sensor_msgs.msg import PointCloud2
from std_srvs.srv import Trigger

from frisicp_ros.node import parameters, shutdown
from frisicp_ros.node.newest_slot import NewestWinsSlot
from frisicp_ros.node.status import NodeStatus
from frisicp_ros.stream.loop import SequentialRegistrar, run_stream, serial_map
from frisicp_ros.stream.outputs import (
    ALWAYS_PUBLISHED,
    OUTPUT_TOPICS,
    MessageTypes,
    build_outputs,
    rclpy_message_types,
)
from frisicp_ros.stream.pairing import Pairer
from frisicp_ros.stream.pipeline import PairOutcome, Rejected, describe
from frisicp_ros.stream.pointcloud2 import stamp_ns
from frisicp_ros.stream.settings import settings_from

if TYPE_CHECKING:
    from frisicp_ros.node.replay import BagReplay

NODE_NAME = "frisicp"
_WARN_THROTTLE_SEC = 2.0
_NO_MODEL_WARN_SEC = 5.0
_WORKER_POLL_SEC = 0.2  # how often an idle worker looks at the stop flag
_WORKER_JOIN_SEC = 10.0  # a running registration is not interruptible; wait for it this long
_WORKER_RESTARTS = 100  # loop failures survived before the worker gives up (and says ERROR)

SUBSCRIPTION_QOS = {
    "sensor_data": qos_profile_sensor_data,  # best effort, volatile, depth 5
    "reliable": QoSProfile(depth=5, reliability=ReliabilityPolicy.RELIABLE),
    # A latched map: receives the last map published before this node started.
    "transient_local": QoSProfile(
        depth=1,
        history=HistoryPolicy.KEEP_LAST,
        reliability=ReliabilityPolicy.RELIABLE,
        durability=DurabilityPolicy.TRANSIENT_LOCAL,
    ),
}
OUTPUT_QOS = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)


@dataclass(frozen=True)
class PendingPair:
    model_cloud: PointCloud2
    data_cloud: PointCloud2
    received_at: float  # time.monotonic() when the data cloud (or the completing cloud) arrived


class RegistrationNode(Node):
    def __init__(self, **kwargs: Any) -> None:
        super().__init__(NODE_NAME, **kwargs)
        parameters.declare(self)
        values = parameters.current_values(self)
        settings = settings_from(values)  # a bad --params-file value fails here, loudly
        self._types: MessageTypes = rclpy_message_types()
        # The one pipeline; only the thread running the stream loop (the worker, or the bag
        # replay) calls it. Parameter changes and resets reach it as requests.
        self._registrar = SequentialRegistrar(settings)
        self._pairer_lock = threading.Lock()
        self._pairer: Pairer[PointCloud2, PointCloud2] = Pairer(settings.pairing, settings.sync_tolerance)
        self._slot: NewestWinsSlot[PendingPair] = NewestWinsSlot()
        self._models_received = 0  # since start or ~/reset (under the pairer lock)
        self._status = NodeStatus()

        self._output_publishers = {
            suffix: self.create_publisher(self._types[type_name], f"~/{suffix}", OUTPUT_QOS)
            for suffix, type_name in OUTPUT_TOPICS.items()
        }
        self._diagnostics_publisher = self.create_publisher(DiagnosticArray, "/diagnostics", 10)
        # With the `bag` parameter the clouds come from a bag instead of subscriptions (replay.py,
        # imported only then: live use needs no rosbags).
        self._replay: BagReplay | None = None
        if values["bag"]:
            from frisicp_ros.node.replay import BagReplay, replay_options

            self._replay = BagReplay(
                self, replay_options(self, values), self._registrar, self.publish_outcome
            )
        else:
            self.create_subscription(
                PointCloud2, "model", self._on_model, SUBSCRIPTION_QOS[str(values["model_qos"])]
            )
            self.create_subscription(  # two parameters: rclpy passes the message info too
                PointCloud2,
                "data",
                self._on_data,  # type: ignore[arg-type]  # rclpy's stubs know one-parameter callbacks only
                SUBSCRIPTION_QOS[str(values["data_qos"])],
            )
        self.create_service(Trigger, "~/reset", self._on_reset)
        self.add_on_set_parameters_callback(self._validate_parameters)
        self.add_post_set_parameters_callback(self._apply_parameters)
        self.create_timer(float(values["diagnostics_period"]), self._publish_diagnostics)

        self._stopping = threading.Event()
        self._handled_pairs = 0  # pairs the worker took to the end (for its restart rule)
        self._worker = threading.Thread(target=self._work, name="frisicp-registration", daemon=True)
        if self._replay is not None:
            self._replay.start()
        else:
            self._worker.start()
        self.get_logger().info(
            f"registering '{self.resolve_topic_name('data')}' onto '{self.resolve_topic_name('model')}'"
            f" ({settings.pairing}, {settings.dims}-D, max_points {settings.max_points or 'unlimited'})"
        )

    # --- inputs (executor callbacks: cheap, never register) ---------------------------------------

    def _on_model(self, msg: PointCloud2) -> None:
        self._status.count_input("model")
        with self._pairer_lock:
            self._models_received += 1
            pairs = self._pairer.add_model(stamp_ns(msg), msg)
        self._hand_over(pairs)

    def _on_data(self, msg: PointCloud2, info: dict[str, int]) -> None:
        """A data cloud; ``info`` (rclpy's message info) has its DDS source and receipt times."""
        now_ns = time.time_ns()
        source, received = info.get("source_timestamp", 0), info.get("received_timestamp", 0)
        if source > 0 and received > 0:
            self._status.count_input("data", (received - source) * 1e-9, (now_ns - received) * 1e-9)
        else:
            self._status.count_input("data")
        with self._pairer_lock:
            pairs = self._pairer.add_data(stamp_ns(msg), msg)
            no_model = self._models_received == 0
        if no_model:
            self._warn_no_model()
        self._hand_over(pairs)

    def _warn_no_model(self) -> None:
        """Data but never a model: most often a latched map missed by a volatile subscription."""
        qos = self.get_parameter("model_qos").value
        hint = (
            "is the model published?"
            if qos == "transient_local"
            else "a map published once (latched) needs model_qos: transient_local"
        )
        self.get_logger().warning(
            f"data clouds arrive on '{self.resolve_topic_name('data')}' but no model cloud has arrived on"
            f" '{self.resolve_topic_name('model')}' (model_qos: {qos}); {hint}",
            throttle_duration_sec=_NO_MODEL_WARN_SEC,
        )

    def _hand_over(self, pairs: list[tuple[PointCloud2, PointCloud2]]) -> None:
        now = time.monotonic()
        for model, data in pairs:
            self._slot.put(PendingPair(model, data, now))

    def _on_reset(self, request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        with self._pairer_lock:
            self._pairer.reset()
            self._models_received = 0
        self._slot.clear()
        self._registrar.request_reset()
        response.success = True
        response.message = "stored model, pending pair and warm start cleared"
        self.get_logger().info(response.message)
        return response

    # --- parameters -----------------------------------------------------------------------------

    def _validate_parameters(self, changes: list[Parameter]) -> SetParametersResult:
        """Reject a change the core would reject, with its reason; the old value stays."""
        try:
            settings_from(parameters.with_changes(self, changes))
        except ValueError as err:
            return SetParametersResult(successful=False, reason=str(err))
        return SetParametersResult(successful=True)

    def _apply_parameters(self, changes: list[Parameter]) -> None:
        settings = settings_from(parameters.current_values(self))
        if any(p.name in ("pairing", "sync_tolerance") for p in changes):
            with self._pairer_lock:  # the stored (latched) model stays
                self._pairer.reconfigure(settings.pairing, settings.sync_tolerance)
        self._registrar.request_settings(settings)
        self.get_logger().info("parameters changed: " + ", ".join(f"{p.name}={p.value!r}" for p in changes))

    # --- the worker -----------------------------------------------------------------------------

    def _work(self) -> None:
        """The live stream loop: the newest pending pair, registered and published, until stopped.

        Per-pair failures are handled inside (the pipeline and ``publish_outcome`` never raise);
        should the loop itself fail (a bug), it is reported and started again, and if even that
        fails the diagnostics say ERROR instead of "registering".
        """
        restarts, handled_before = 0, -1
        while not self._stopping.is_set():
            try:
                run_stream(self._pending_pairs(), self._registrar, self._publish_pending, serial_map)
                return
            except Exception as err:  # noqa: BLE001 - reported; a silent dead worker is worse
                if self._stopping.is_set():
                    return
                # Give up only when failures come back to back, without a pair handled between.
                restarts = restarts + 1 if self._handled_pairs == handled_before else 1
                handled_before = self._handled_pairs
                self._status.record_error(f"stream loop: {describe(err)}")
                self.get_logger().error(
                    f"registration loop failed ({describe(err)}); restarting",
                    throttle_duration_sec=_WARN_THROTTLE_SEC,
                )
                if restarts > _WORKER_RESTARTS:
                    self._status.record_worker_stopped(describe(err))
                    self.get_logger().fatal(f"registration worker stopped: {describe(err)}")
                    return

    def _pending_pairs(self) -> Iterator[PendingPair]:
        while not self._stopping.is_set():
            pending = self._slot.take(timeout=_WORKER_POLL_SEC)
            if pending is None:
                self._registrar.apply_requests()  # idle: a reset or new settings take effect now
            else:
                yield pending

    def _publish_pending(self, pending: PendingPair, outcome: PairOutcome) -> None:
        self._handled_pairs += 1
        self.publish_outcome(outcome, pending.data_cloud, pending.received_at)

    # --- outputs --------------------------------------------------------------------------------

    def publish_outcome(
        self, outcome: PairOutcome, data_cloud: PointCloud2, received_at: float | None = None
    ) -> None:
        """Publish one pair's outputs (or warn about its rejection or implausible result) and
        count it. Never raises: a failure to publish one pair is counted, logged and survived.

        The single publishing path: the live stream loop calls it, and so does the bag replay
        (``received_at`` None: no latency is recorded). Runs in the stream loop's thread.
        """
        try:
            self._publish(outcome, data_cloud, received_at)
        except Exception as err:  # noqa: BLE001 - the worker must outlive any one pair
            if self._stopping.is_set() or not self.context.ok():
                return  # shutting down: the publishers went away under the last pair
            self._status.record_error(describe(err))
            self.get_logger().error(
                f"publishing the pair stamped {outcome.stamp} failed: {describe(err)}",
                throttle_duration_sec=_WARN_THROTTLE_SEC,
            )

    def _publish(self, outcome: PairOutcome, data_cloud: PointCloud2, received_at: float | None) -> None:
        started = time.perf_counter()
        if isinstance(outcome, Rejected):
            self.get_logger().warning(f"skipped: {outcome.reason}", throttle_duration_sec=_WARN_THROTTLE_SEC)
            self._status.record(outcome, None, 0.0)
            return
        if not outcome.reliable:
            self.get_logger().warning(
                f"implausible result not published (scale {outcome.result.similarity.scale:.6g}):"
                f" {outcome.reason}",
                throttle_duration_sec=_WARN_THROTTLE_SEC,
            )
            self._status.record(outcome, None, 0.0)
            return
        topics: tuple[str, ...] = ALWAYS_PUBLISHED
        if (
            self._registrar.settings.publish_aligned
            and self._output_publishers["aligned"].get_subscription_count()
        ):
            topics = (*ALWAYS_PUBLISHED, "aligned")
        for suffix, message in build_outputs(outcome, data_cloud, self._types, topics).items():
            self._output_publishers[suffix].publish(message)
        latency = None if received_at is None else time.monotonic() - received_at
        self._status.record(outcome, latency, time.perf_counter() - started)

    def _publish_diagnostics(self) -> None:
        if self._replay is None and not self._worker.is_alive() and not self._stopping.is_set():
            self._status.record_worker_stopped("the registration thread has ended")
        with self._pairer_lock:
            unpaired, has_model = self._pairer.unpaired_data, self._pairer.latest_model is not None
        report = self._status.report(
            self._slot.dropped, unpaired, has_model or self._pairer.mode != "latest_model"
        )
        status = DiagnosticStatus(
            level=bytes([report.level]),
            name=f"{self.get_name()}: registration",
            message=report.message,
            hardware_id=self.get_fully_qualified_name(),
            values=[KeyValue(key=key, value=value) for key, value in report.values.items()],
        )
        array = DiagnosticArray(status=[status])
        array.header.stamp = self.get_clock().now().to_msg()  # diagnostics describe "now", not a cloud
        self._diagnostics_publisher.publish(array)

    # --- shutdown -------------------------------------------------------------------------------

    def destroy_node(self) -> None:
        """Stop the worker before the publishers it uses are destroyed."""
        self._stopping.set()
        self._slot.close()
        if self._replay is not None:
            self._replay.stop(_WORKER_JOIN_SEC)
        if self._worker.is_alive() and threading.current_thread() is not self._worker:
            self._worker.join(_WORKER_JOIN_SEC)
        super().destroy_node()


def main(args: list[str] | None = None) -> int:
    """Console script ``register_node``; SIGINT, SIGTERM (any number of them) and external
    shutdown end it quietly with code 0 (see ``shutdown``)."""
    signals = shutdown.install()  # before rclpy.init, which chains its handlers to this one
    rclpy.init(args=args)
    node: RegistrationNode | None = None
    try:
        if not signals.requested:
            node = RegistrationNode()
            rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except (ValueError, ParameterException) as err:  # e.g. a bad --params-file value
        if not signals.requested:
            rclpy.logging.get_logger(NODE_NAME).fatal(f"invalid parameters: {err}")
            return 2
    except Exception:
        if not signals.requested:
            raise
        # A signal during start-up: rclpy's context went away under the constructor.
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
        shutdown.ignore_from_now_on()
    return 0


if __name__ == "__main__":
    sys.exit(main())
