"""Quiet shutdown of the node process under any number of SIGINT / SIGTERM.

rclpy's own handlers (installed by ``rclpy.init``) shut the context down on the first signal, which
ends ``spin``; they then call the handler that was installed before them. Python's default
SIGINT handler raises KeyboardInterrupt wherever the main thread happens to be, and a second
signal (``ros2 launch`` forwards one after the terminal's own Ctrl-C) lands inside the shutdown
itself: a traceback and exit code -2. :func:`install` therefore puts a handler in place *before*
``rclpy.init`` that only records the signal. rclpy chains to it, so the first signal still stops
the node through rclpy, and every further one is absorbed while the node finishes cleanly.
(Installing it after ``rclpy.init`` would replace rclpy's handler: Python re-registers its own.)

At the very end, :func:`ignore_from_now_on`: Python's finalization resets every signal with a
Python handler to its default action, and tearing down DDS takes tens of milliseconds more, so a
second Ctrl-C 50 ms after the first used to kill the exiting process (exit code -2).
"""

from __future__ import annotations

import signal
import threading
from types import FrameType

STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)


class StopSignals:
    """Counts stop signals; never raises from the handler."""

    def __init__(self) -> None:
        self.received: list[int] = []
        self._stop = threading.Event()

    @property
    def requested(self) -> bool:
        return self._stop.is_set()

    def _on_signal(self, signum: int, frame: FrameType | None) -> None:
        self.received.append(signum)
        self._stop.set()


def install() -> StopSignals:
    """Record SIGINT and SIGTERM instead of raising; call in the main thread before rclpy.init."""
    signals = StopSignals()
    for signum in STOP_SIGNALS:
        signal.signal(signum, signals._on_signal)
    return signals


def ignore_from_now_on() -> None:
    """The process is exiting: SIGINT and SIGTERM may no longer change how (finalization keeps an
    ignored signal ignored)."""
    for signum in STOP_SIGNALS:
        signal.signal(signum, signal.SIG_IGN)
