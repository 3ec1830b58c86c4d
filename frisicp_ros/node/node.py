"""``register_node``: the FRISICP ROS 2 node (thin glue around the shared pipeline).

Subscribes ``model`` and ``data`` (sensor_msgs/PointCloud2) and ``~/initial_guess``
(geometry_msgs/PoseWithCovarianceStamped), pairs the clouds (``pairing``), hands the newest pair
to one worker thread (registration never runs in an executor callback), and publishes
``~/transform``, ``~/pose``, ``~/scale``, ``~/rms``, ``~/similarity``, ``~/aligned``, optionally
``/tf``, and ``/diagnostics``. See docs/node.md.

:class:`RegistrationParts` is everything the node does; :class:`RegistrationNode` runs it from
construction to destruction, ``frisicp_ros.node.lifecycle`` between its lifecycle transitions.
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
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import rclpy
import rclpy.logging
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import PoseWithCovarianceStamped
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
from frisicp_ros.node.message_types import rclpy_message_types
from frisicp_ros.node.newest_slot import NewestWinsSlot
from frisicp_ros.node.status import NodeStatus
from frisicp_ros.stream.guess import describe_guess, guess_from_message
from frisicp_ros.stream.loop import SequentialRegistrar, run_stream, serial_map
from frisicp_ros.stream.outputs import (
    ALWAYS_PUBLISHED,
    OUTPUT_TOPICS,
    TF_TYPE,
    MessageTypes,
    build_outputs,
    scaled_frame,
    tf_message,
)
from frisicp_ros.stream.pairing import Pairer, PairingMode
from frisicp_ros.stream.pipeline import PairOutcome, Registered, Rejected, describe
from frisicp_ros.stream.settings import SubscriptionQos, Value, settings_from
from frisicp_ros.stream.stamps import stamp_ns

if TYPE_CHECKING:
    from frisicp_ros.node.replay import BagReplay

NODE_NAME = "frisicp"
_WARN_THROTTLE_SEC = 2.0
_NO_MODEL_WARN_SEC = 5.0
_WORKER_POLL_SEC = 0.2  # how often an idle worker looks at the stop flag
_WORKER_JOIN_SEC = 10.0  # a running registration is not interruptible; wait for it this long
_WORKER_RESTARTS = 100  # loop failures survived before the worker gives up (and says ERROR)

SUBSCRIPTION_QOS = {
    SubscriptionQos.SENSOR_DATA: qos_profile_sensor_data,  # best effort, volatile, depth 5
    SubscriptionQos.RELIABLE: QoSProfile(depth=5, reliability=ReliabilityPolicy.RELIABLE),
    # A latched map: receives the last map published before this node started.
    SubscriptionQos.TRANSIENT_LOCAL: QoSProfile(
        depth=1,
        history=HistoryPolicy.KEEP_LAST,
        reliability=ReliabilityPolicy.RELIABLE,
        durability=DurabilityPolicy.TRANSIENT_LOCAL,
    ),
}
OUTPUT_QOS = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
# tf2_ros's TransformBroadcaster QoS (DynamicBroadcasterQoS): reliable, volatile, depth 100.
TF_QOS = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
GUESS_QOS = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE)  # RViz's /initialpose: reliable
PROFILE_FILE = "fastdds_large_messages.xml"


def shipped_dds_profile() -> str:
    """Where config/fastdds_large_messages.xml is installed: the package's share directory (a
    workspace, found through the ament index) or, for pip installs, the environment's share/."""
    try:
        from ament_index_python.packages import get_package_share_directory

        share = Path(get_package_share_directory("frisicp_ros"))
    except (ImportError, LookupError, ValueError, OSError):  # no AMENT_PREFIX_PATH: a pip install
        share = Path(sys.prefix) / "share" / "frisicp_ros"
    return str(share / "config" / PROFILE_FILE)


@dataclass(frozen=True)
class PendingPair:
    model_cloud: PointCloud2
    data_cloud: PointCloud2
    received_at: float  # time.monotonic() when the data cloud (or the completing cloud) arrived


PublisherFactory = Callable[..., Any]  # Node.create_publisher or LifecycleNode.create_lifecycle_publisher


class RegistrationParts:
    """The node's work, for a ``Node`` or a ``LifecycleNode`` (mixed in before it).

    :meth:`set_up` makes the pipeline, publishers, subscriptions, service and timer,
    :meth:`start_work` starts the worker (or the bag replay), :meth:`stop_work` stops it, and
    :meth:`tear_down` destroys what ``set_up`` made. The plain node sets up and starts when it is
    constructed and stops in ``destroy_node``; the managed node does the four in its configure,
    activate, deactivate and cleanup transitions.
    """

    # Everything below lives in rclpy's Node, which the concrete classes also derive from.
    get_logger: Callable[[], Any]
    get_parameter: Callable[[str], Parameter]
    get_name: Callable[[], str]
    get_fully_qualified_name: Callable[[], str]
    get_clock: Callable[[], Any]
    resolve_topic_name: Callable[..., str]
    create_subscription: Callable[..., Any]
    create_service: Callable[..., Any]
    create_timer: Callable[..., Any]
    destroy_subscription: Callable[..., Any]
    destroy_service: Callable[..., Any]
    destroy_timer: Callable[..., Any]
    context: Any

    def set_up(self, create_publisher: PublisherFactory, values: dict[str, Value]) -> None:
        """Build everything from the parameter ``values`` (a bad value raises ValueError here)."""
        settings = settings_from(values)  # a bad --params-file value fails here, loudly
        self._types: MessageTypes = rclpy_message_types()
        # The one pipeline; only the thread running the stream loop (the worker, or the bag
        # replay) calls it. Parameter changes and resets reach it as requests.
        self._registrar = SequentialRegistrar(settings)
        self._pairer_lock = threading.Lock()
        self._pairer: Pairer[PointCloud2, PointCloud2] = Pairer(settings.pairing, settings.sync_tolerance)
        self._slot: NewestWinsSlot[PendingPair] = NewestWinsSlot()
        self._models_received = 0  # since start or ~/reset (under the pairer lock)
        self._status = NodeStatus(
            stale_after=float(values["stale_after"]), fix_for_lost_scans=_lost_scan_fix()
        )
        self._depth_step_advice = ""  # the last advice logged about the data clouds' depth steps
        self._output_publishers = {
            suffix: create_publisher(self._types[type_name], f"~/{suffix}", OUTPUT_QOS)
            for suffix, type_name in OUTPUT_TOPICS.items()
        }
        self._tf_publisher = None
        if values["publish_tf"]:
            if TF_TYPE in self._types:
                self._tf_publisher = create_publisher(self._types[TF_TYPE], "/tf", TF_QOS)
                self._status.set_tf("publishing (child frame: the data frame scaled by s)")
            else:
                message = (
                    "publish_tf is true but tf2_msgs cannot be imported (it is not on PyPI: run the"
                    " node in a ROS 2 installation that has tf2_msgs); /tf is NOT published,"
                    " ~/pose and ~/transform carry the same estimate"
                )
                self.get_logger().warning(message)
                self._status.set_tf("requested, but tf2_msgs is not installed: not published")
        self._diagnostics_publisher = create_publisher(DiagnosticArray, "/diagnostics", 10)
        self._values = values
        self._inputs: list[Any] = []
        if not values["bag"]:
            self._inputs = [
                self.create_subscription(
                    PointCloud2,
                    "model",
                    self._on_model,
                    SUBSCRIPTION_QOS[SubscriptionQos(values["model_qos"])],
                ),
                self.create_subscription(  # two parameters: rclpy passes the message info too
                    PointCloud2,
                    "data",
                    self._on_data,  # rclpy passes (msg, info) to a two-parameter callback
                    SUBSCRIPTION_QOS[SubscriptionQos(values["data_qos"])],
                ),
            ]
        # Guesses are taken in replay mode too: the replay is a live stream for everything else.
        self._inputs.append(
            self.create_subscription(PoseWithCovarianceStamped, "~/initial_guess", self._on_guess, GUESS_QOS)
        )
        self._reset_service = self.create_service(Trigger, "~/reset", self._on_reset)
        self._diagnostics_timer = self.create_timer(
            float(values["diagnostics_period"]), self._publish_diagnostics
        )
        self._stopping = threading.Event()
        self._stopping.set()  # not working until start_work
        self._active = False  # data clouds are taken only while working
        self._handled_pairs = 0  # pairs the worker took to the end (for its restart rule)
        self._worker = threading.Thread(target=self._work, name="frisicp-registration", daemon=True)
        self._replay: BagReplay | None = None

    def start_work(self) -> None:
        """Start registering: the worker, or (``bag`` parameter) the bag replay."""
        self._stopping = threading.Event()
        self._status.mark_started()
        self._active = True
        values = self._values
        if values["bag"]:
            # Imported only now: live use needs no rosbags.
            from frisicp_ros.node.replay import BagReplay, replay_options

            self._replay = BagReplay(
                self,  # type: ignore[arg-type]  # the concrete classes are rclpy Nodes
                replay_options(self, values),  # type: ignore[arg-type]
                self._registrar,
                self.publish_outcome,
            )
            self._replay.start()
        else:
            self._worker = threading.Thread(target=self._work, name="frisicp-registration", daemon=True)
            self._worker.start()
        settings = self._registrar.settings
        self.get_logger().info(
            f"registering '{self.resolve_topic_name('data')}' onto '{self.resolve_topic_name('model')}'"
            f" ({settings.pairing}, {settings.dims}-D, max_points {settings.max_points or 'unlimited'})"
        )

    def stop_work(self) -> None:
        """Stop the worker (or replay), waiting for a running registration; pending pairs go."""
        self._active = False
        self._stopping.set()
        self._slot.close()
        if self._replay is not None:
            self._replay.stop(_WORKER_JOIN_SEC)
            self._replay = None
        if self._worker.is_alive() and threading.current_thread() is not self._worker:
            self._worker.join(_WORKER_JOIN_SEC)
        self._slot = NewestWinsSlot()  # a fresh one for a later start

    def tear_down(self, destroy_publisher: Callable[[Any], Any]) -> None:
        """Destroy what :meth:`set_up` made (the worker must be stopped)."""
        for subscription in self._inputs:
            self.destroy_subscription(subscription)
        self._inputs = []
        self.destroy_service(self._reset_service)
        self.destroy_timer(self._diagnostics_timer)
        publishers = [*self._output_publishers.values(), self._diagnostics_publisher]
        if self._tf_publisher is not None:
            publishers.append(self._tf_publisher)
        for publisher in publishers:
            destroy_publisher(publisher)
        self._output_publishers = {}
        self._tf_publisher = None

    # --- inputs (executor callbacks: cheap, never register) ---------------------------------------

    def _on_model(self, msg: PointCloud2) -> None:
        self._status.count_input("model")
        with self._pairer_lock:
            self._models_received += 1
            pairs = self._pairer.add_model(stamp_ns(msg), msg)
        self._hand_over(pairs)

    def _on_data(self, msg: PointCloud2, info: dict[str, int]) -> None:
        """A data cloud; ``info`` (rclpy's message info) has its DDS source and receipt times."""
        if not self._active:  # a managed node while inactive: not taken
            return
        now_ns = time.time_ns()
        source, received = info.get("source_timestamp", 0), info.get("received_timestamp", 0)
        self._status.count_data(stamp_ns(msg))
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
            if qos == SubscriptionQos.TRANSIENT_LOCAL
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
        self._status.record_reset()
        response.success = True
        response.message = "stored model, pending pair and warm start cleared"
        self.get_logger().info(response.message)
        return response

    def _on_guess(self, msg: PoseWithCovarianceStamped) -> None:
        """An initial guess (RViz's "2D Pose Estimate"): the next registration searches around it,
        cold; tracking goes on from its result. A guess that cannot be used is logged, not taken."""
        try:
            guess = self._guess_of(msg)
        except ValueError as err:
            self.get_logger().warning(f"initial guess ignored: {err}")
            self._status.record_guess(f"ignored: {err}")
            return
        self._registrar.request_guess(guess)
        self._status.record_guess(f"taken: {describe_guess(guess)}")
        self.get_logger().info(f"initial guess for the next registration: {describe_guess(guess)}")

    def _guess_of(self, msg: PoseWithCovarianceStamped) -> Any:
        frame = str(msg.header.frame_id).lstrip("/")
        with self._pairer_lock:
            model = self._pairer.latest_model
        settings = self._registrar.pending_settings or self._registrar.settings
        model_frame = settings.model_frame or (str(model.header.frame_id).lstrip("/") if model else "")
        if frame and model_frame and frame != model_frame:
            raise ValueError(
                f"it is in frame '{frame}' but the model clouds are in '{model_frame}' (this node does"
                " not transform guesses: send it in the model frame)"
            )
        scale = float(self.get_parameter("initial_scale").value)
        return guess_from_message(msg, settings.dims, scale or None)

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
        if isinstance(outcome, Registered) and outcome.depth_step_advice != self._depth_step_advice:
            self._depth_step_advice = outcome.depth_step_advice  # said once per finding, not per pair
            if outcome.depth_step_advice:
                self.get_logger().warning(outcome.depth_step_advice)
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
        if self._tf_publisher is not None:
            child = scaled_frame(outcome.data_frame, self._registrar.settings.tf_child_frame)
            self._tf_publisher.publish(tf_message(outcome, child, self._types))
        latency = None if received_at is None else time.monotonic() - received_at
        self._status.record(outcome, latency, time.perf_counter() - started)

    def _publish_diagnostics(self) -> None:
        if self._replay is None and not self._worker.is_alive() and not self._stopping.is_set():
            self._status.record_worker_stopped("the registration thread has ended")
        with self._pairer_lock:
            unpaired, has_model = self._pairer.unpaired_data, self._pairer.latest_model is not None
        report = self._status.report(
            self._slot.dropped,
            unpaired,
            has_model or self._pairer.mode != PairingMode.LATEST_MODEL,
            guess_pending=self._registrar.pending_guess is not None,
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


def _lost_scan_fix() -> str:
    return (
        "large clouds need DDS configured for them: give the node and the cloud's publisher the"
        f" shipped Fast DDS profile (export FASTRTPS_DEFAULT_PROFILES_FILE={shipped_dds_profile()};"
        " the launch file's large_messages_profile), or data_qos: reliable with a reliable publisher"
    )


class RegistrationNode(RegistrationParts, Node):
    """The node, registering from construction until ``destroy_node``."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(NODE_NAME, **kwargs)
        parameters.declare(self)
        self.set_up(self.create_publisher, parameters.current_values(self))
        self.add_on_set_parameters_callback(self._validate_parameters)
        self.add_post_set_parameters_callback(self._apply_parameters)
        self.start_work()

    def destroy_node(self) -> None:
        """Stop the worker before the publishers it uses are destroyed."""
        self.stop_work()
        super().destroy_node()


def main(args: list[str] | None = None) -> int:
    """Console script ``register_node``."""
    return run_node_process(RegistrationNode, args)


def run_node_process(make_node: Callable[[], Node], args: list[str] | None = None) -> int:
    """Build a node and spin it until the process is stopped: the body of a console script.

    SIGINT, SIGTERM (any number of them) and external shutdown (also one that a publishing
    callback runs into) end it quietly with code 0 (see ``shutdown``); a parameter value the
    node refuses at start-up (a bad ``--params-file``) ends it with code 2 and the reason,
    without a traceback.
    """
    signals = shutdown.install()  # before rclpy.init, which chains its handlers to this one
    rclpy.init(args=args)
    node: Node | None = None
    try:
        if not signals.requested:
            node = make_node()
            rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except (ValueError, ParameterException) as err:  # e.g. a bad --params-file value
        if not signals.requested:
            rclpy.logging.get_logger(NODE_NAME).fatal(f"invalid parameters: {err}")
            return 2
    except Exception:
        if not signals.requested and rclpy.ok():
            raise
        # A signal during start-up: rclpy's context went away under the constructor. Or the
        # context was shut down from inside (bag_exit_on_end, from the replay thread) while a
        # callback was publishing: rclpy raised "publisher's context is invalid" out of spin.
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
        shutdown.ignore_from_now_on()
    return 0


if __name__ == "__main__":
    sys.exit(main())
