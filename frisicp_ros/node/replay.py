"""Bag replay for ``register_node``: the node reads its clouds from a bag instead of subscribing.

With the ``bag`` parameter set, the node opens the bag with rosbags (no ``ros2 bag`` needed),
pairs and registers every pair with the same code as ``frisicp bag`` (``bag_pairs``) and the
node's own pipeline, and publishes the outputs through the node's publishing path, on the live
graph. Which bag topics it reads follows the subscriptions' names, so ``-r data:=/points``
selects ``/points`` in the bag just as it would live.

Its parameters (``bag``, ``bag_rate``, ``bag_delay``, ``bag_wait_for_subscribers``,
``bag_exit_on_end``; read-only) are rows of the settings table like every other. Each output is
released at its data cloud's recorded time (scaled by ``bag_rate``), like a live sensor, or as
soon as computed when the registration is the slower of the two; a pair is never dropped, so slow
registrations make the replay late rather than lossy. In replay mode the node's live worker does
not run: this thread is the one that drives the node's pipeline (through the shared stream loop).
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass

from rclpy.duration import Duration
from rclpy.node import Node

from frisicp_ros.bag.pairs import BagPair, PairReading
from frisicp_ros.bag.reader import BagError, open_bag, require_pointcloud2_topic
from frisicp_ros.stream.loop import SequentialRegistrar, run_stream, serial_map
from frisicp_ros.stream.pipeline import PairOutcome
from frisicp_ros.stream.settings import Value

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


def replay_options(node: Node, values: Mapping[str, Value]) -> ReplayOptions:
    """The replay's options from the node's parameter values; the topics follow the remappings.

    Raises ValueError when the bag cannot be replayed (unreadable, topics missing or not clouds),
    so the node fails at start-up with the reason, as for any invalid parameter.
    """
    options = ReplayOptions(
        bag=str(values["bag"]),
        model_topic=node.resolve_topic_name("model"),
        data_topic=node.resolve_topic_name("data"),
        rate=float(values["bag_rate"]),
        delay=float(values["bag_delay"]),
        wait_for_subscribers=int(values["bag_wait_for_subscribers"]),
        exit_on_end=bool(values["bag_exit_on_end"]),
    )
    try:
        with open_bag(options.bag) as reader:
            for topic in (options.model_topic, options.data_topic):
                require_pointcloud2_topic(reader, topic)
    except BagError as err:
        raise ValueError(
            f"bag: {err} (choose the bag's topics with -r model:=TOPIC -r data:=TOPIC)"
        ) from None
    return options


class _Stopped(Exception):  # noqa: N818 - control flow, not an error
    """The node is shutting down: leave the stream loop."""


class BagReplay:
    """A thread that replays the bag through the node's registrar and ``publish``; ``stop()`` ends it."""

    def __init__(
        self,
        node: Node,
        options: ReplayOptions,
        registrar: SequentialRegistrar,
        publish: Callable[[PairOutcome, object], None],
    ) -> None:
        self.node = node
        self.options = options
        self.registrar = registrar
        self.publish = publish
        self.published = 0
        self._first: tuple[int, float] | None = None  # (bag time, monotonic time) of the first output
        self._stopping = threading.Event()
        self._thread = threading.Thread(target=self._run, name="frisicp-bag-replay", daemon=True)

    def start(self) -> None:
        self._thread.start()

    def stop(self, timeout: float) -> None:
        self._stopping.set()
        if self._thread.is_alive() and threading.current_thread() is not self._thread:
            self._thread.join(timeout)

    def _emit(self, pair: BagPair, outcome: PairOutcome) -> None:
        """Publish at the data cloud's recorded time (scaled by the rate), or now if that has passed."""
        self._first = self._first or (pair.data.bag_ns, time.monotonic())
        rate = self.options.rate
        due = self._first[1] + (pair.data.bag_ns - self._first[0]) / 1e9 / rate if rate > 0 else 0.0
        if self._stopping.wait(max(0.0, due - time.monotonic())):
            raise _Stopped
        self.publish(outcome, pair.data_cloud)
        self.published += 1

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
        started = time.monotonic()
        try:
            with open_bag(options.bag) as reader:
                reading = PairReading.paired_as(
                    self.registrar.settings, reader, options.model_topic, options.data_topic
                )
                run_stream(reading, self.registrar, self._emit, serial_map)
        except _Stopped:
            return
        except BagError as err:
            reading_stopped: str | None = str(err)
        else:
            reading_stopped = reading.stopped
        if reading_stopped:
            logger.error(f"bag replay stopped after {self.published} pairs: {reading_stopped}")
        logger.info(f"bag replay done: {self.published} pairs in {time.monotonic() - started:.2f} s")
        if options.exit_on_end and not self._stopping.is_set():
            # Outputs are reliable but volatile: let subscribers take them before we go.
            for publisher in self.node.publishers:
                publisher.wait_for_all_acked(Duration(seconds=_ACK_TIMEOUT_SEC))
            logger.info("bag replay finished: shutting down (bag_exit_on_end)")
            self.node.context.try_shutdown()
