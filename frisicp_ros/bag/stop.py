"""Ctrl-C and SIGTERM during ``frisicp bag``: stop cleanly, keep every result, never hang.

- The first SIGINT or SIGTERM is a request: the pair in hand is finished and written to every
  output (so the JSONL and the result bag hold the same pairs), then the run stops and the
  outputs are closed (the result bag finished and renamed).
- The second abandons the registration being waited for, at once: :meth:`StopRequest.interruptible`
  marks the only places where that is safe (computing or awaiting a registration). Anywhere else
  (writing an output, starting or stopping worker processes) it waits for the next such point, so
  a signal never lands inside a half-written result or the process pool's bookkeeping.
- Any further signal is absorbed, also after the run has returned (the command is exiting):
  the stop already under way is bounded.

The exit code tells which signal stopped the run: 130 (SIGINT), 143 (SIGTERM), as shells report.
Only in the main thread, where Python delivers signals; elsewhere nothing is installed.
"""

from __future__ import annotations

import signal
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from types import FrameType

STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)


class StopRequested(KeyboardInterrupt):
    """Raised to leave the run (a KeyboardInterrupt, so no ``except Exception`` swallows it)."""


class StopRequest:
    def __init__(self) -> None:
        self.signals: list[int] = []
        self._interruptible = False
        self._previous: dict[int, Callable[[int, FrameType | None], object] | int | None] = {}

    @property
    def requested(self) -> bool:
        return bool(self.signals)

    @property
    def exit_code(self) -> int:
        """128 + the first signal's number, as a shell reports a process its signal ended."""
        return 128 + (self.signals[0] if self.signals else signal.SIGINT)

    @property
    def description(self) -> str:
        return "terminated (SIGTERM)" if self.signals[:1] == [signal.SIGTERM] else "interrupted"

    def __enter__(self) -> StopRequest:
        if threading.current_thread() is threading.main_thread():
            for signum in STOP_SIGNALS:
                self._previous[signum] = signal.signal(signum, self._on_signal)
        return self

    def __exit__(self, *exc_info: object) -> None:
        for signum, previous in self._previous.items():
            # Once stopping, the command is on its way out: a signal after this point (the
            # second of a double Ctrl-C often is) must not turn the exit into a traceback.
            signal.signal(signum, signal.SIG_IGN if self.signals else previous)

    def _on_signal(self, signum: int, frame: FrameType | None) -> None:
        self.signals.append(signum)
        if len(self.signals) == 2 and self._interruptible:
            raise StopRequested

    def check(self) -> None:
        """Between pairs: stop if asked to."""
        if self.signals:
            raise StopRequested

    @contextmanager
    def interruptible(self) -> Iterator[None]:
        """Where a second signal may abandon the work at once (a registration, or waiting for one)."""
        if len(self.signals) >= 2:
            raise StopRequested
        self._interruptible = True
        try:
            yield
        finally:
            self._interruptible = False
