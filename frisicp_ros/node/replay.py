"""Bag replay for ``register_node``: the node reads its clouds from a bag instead of subscribing.

With the ``bag`` parameter set, the node opens the bag with rosbags (no ``ros2 bag`` needed),
pairs and registers every pair with the same code as ``frisicp bag`` (``bag_pairs``) and the
node's own pipeline, and publishes the outputs through the node's publishing path, on the live
graph. Which bag topics it reads follows the subscriptions' names, so ``-r data:=/points``
selects ``/points`` in the bag just as it would live.

Parameters (read-only, set at start-up):

- ``bag`` (string, "" = live mode): rosbag2 folder, ``.db3``/``.mcap`` file or ROS 1 ``.bag``.
- ``bag_rate`` (double, 1.0): 1 = the recorded rate, 2 = twice as fast, 0 = as fast as possible.
  Each pair is released at its data cloud's recorded time (scaled), like a live sensor; a pair
  is never dropped, so slow registrations make the replay late rather than lossy.
- ``bag_delay`` (double, 1.0 s): wait before the first pair so subscribers can discover the node
  (what ``ros2 bag play --delay`` is for; outputs are volatile).
- ``bag_wait_for_subscribers`` (int, 0): before that delay, wait until ``~/transform`` has this
  many subscribers, so a stack that starts later still gets the first outputs.
- ``bag_exit_on_end`` (bool, true): shut the node down when the bag is done (after subscribers
  acknowledged the outputs); false = stay up, idle.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from dataclasses import dataclass

from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor
from rclpy.duration import Duration
from rclpy.node import Node

from frisicp_ros.bag.pairs import PairReading
from frisicp_ros.bag.reader import BagError, open_bag, require_pointcloud2_topic
from frisicp_ros.stream.pairing import Pairer
from frisicp_ros.stream.pipeline import PairOutcome, RegistrationPipeline

_ACK_TIMEOUT_SEC = 5.0


@dataclass(frozen=True)
class ReplayOptions:
    bag: str
    model_topic: str
    data_topic: str
    rate: float
    delay: float
    wait_for_subscribers: int
    exit_on_end: bool


def declare_replay_parameters(node: Node) -> ReplayOptions | None:
    """Declare the replay parameters; their values, or None when ``bag`` is empty (live mode).

    Raises ValueError when the bag cannot be replayed (unreadable, topics missing or not clouds),
    so the node fails at start-up with the reason, as for any invalid parameter.
    """

    def declare(
        name: str,
        default: object,
        description: str,
        float_range: tuple[float, float] | None = None,
    ) -> object:
        descriptor = ParameterDescriptor(name=name, description=description, read_only=True)
        if float_range:
            descriptor.floating_point_range = [
                FloatingPointRange(from_value=float_range[0], to_value=float_range[1], step=0.0)
            ]
        if isinstance(default, int) and not isinstance(default, bool):
            descriptor.integer_range = [IntegerRange(from_value=0, to_value=1000, step=1)]
        return node.declare_parameter(name, default, descriptor).value

    bag = str(declare("bag", "", "replay this bag instead of subscribing ('' = live)"))
    rate = float(
        declare("bag_rate", 1.0, "replay speed: 1 = recorded rate, 0 = as fast as possible", (0.0, 1000.0))
    )
    delay = float(declare("bag_delay", 1.0, "seconds to wait before replaying (discovery)", (0.0, 3600.0)))
    wait_for_subscribers = int(
        declare("bag_wait_for_subscribers", 0, "wait for this many ~/transform subscribers before replaying")
    )
    exit_on_end = bool(declare("bag_exit_on_end", True, "shut down when the bag is done (false: idle)"))
    if not bag:
        return None
    options = ReplayOptions(
        bag,
        node.resolve_topic_name("model"),
        node.resolve_topic_name("data"),
        rate,
        delay,
        wait_for_subscribers,
        exit_on_end,
    )
    try:
        with open_bag(bag) as reader:
            for topic in (options.model_topic, options.data_topic):
                require_pointcloud2_topic(reader, topic)
    except BagError as err:
        raise ValueError(
            f"bag: {err} (choose the bag's topics with -r model:=TOPIC -r data:=TOPIC)"
        ) from None
    return options


class BagReplay:
    """A thread that replays the bag through ``pipeline`` and ``publish``; ``stop()`` ends it."""

    def __init__(
        self,
        node: Node,
        options: ReplayOptions,
        pipeline: RegistrationPipeline,
        publish: Callable[[PairOutcome], None],
    ) -> None:
        self.node = node
        self.options = options
        self.pipeline = pipeline
        self.publish = publish
        self._stopping = threading.Event()
        self._thread = threading.Thread(target=self._run, name="frisicp-bag-replay", daemon=True)

    def start(self) -> None:
        self._thread.start()

    def stop(self, timeout: float) -> None:
        self._stopping.set()
        if self._thread.is_alive() and threading.current_thread() is not self._thread:
            self._thread.join(timeout)

    def _run(self) -> None:
        logger = self.node.get_logger()
        options = self.options
        if options.wait_for_subscribers:
            logger.info(f"bag replay waits for {options.wait_for_subscribers} subscriber(s) of ~/transform")
        while (
            self.node.count_subscribers(self.node.resolve_topic_name("~/transform"))
            < options.wait_for_subscribers
        ):
            if self._stopping.wait(0.1):
                return
        if self._stopping.wait(options.delay):
            return
        settings = self.pipeline.settings
        published = 0
        started = time.monotonic()
        try:
            with open_bag(options.bag) as reader:
                reading = PairReading(
                    reader,
                    options.model_topic,
                    options.data_topic,
                    Pairer(settings.pairing, settings.sync_tolerance),
                )
                first: tuple[int, float] | None = None  # (bag time, monotonic time) of the first output
                for pair in reading:
                    outcome = self.pipeline.process(pair.model.cloud, pair.data.cloud)
                    # Outputs go out at their data clouds' recorded times (scaled by the rate),
                    # or as soon as computed when the registration is the slower of the two.
                    first = first or (pair.data.bag_ns, time.monotonic())
                    due = (
                        first[1] + (pair.data.bag_ns - first[0]) / 1e9 / options.rate
                        if options.rate > 0
                        else 0.0
                    )
                    if self._stopping.wait(max(0.0, due - time.monotonic())):
                        return
                    self.publish(outcome)
                    published += 1
        except BagError as err:
            reading_stopped: str | None = str(err)
        else:
            reading_stopped = reading.stopped
        if reading_stopped:
            logger.error(f"bag replay stopped after {published} pairs: {reading_stopped}")
        logger.info(f"bag replay done: {published} pairs in {time.monotonic() - started:.2f} s")
        if options.exit_on_end and not self._stopping.is_set():
            # Outputs are reliable but volatile: let subscribers take them before we go.
            for publisher in self.node.publishers:
                publisher.wait_for_all_acked(Duration(seconds=_ACK_TIMEOUT_SEC))
            logger.info("bag replay finished: shutting down (bag_exit_on_end)")
            self.node.context.try_shutdown()
