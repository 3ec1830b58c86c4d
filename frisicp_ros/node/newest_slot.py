"""A one-item hand-over between executor callbacks and the registration worker. No ROS.

Registration takes longer than a cloud period on slow machines; queueing pairs would grow the
latency without bound. The slot keeps only the newest pair: putting into a full slot replaces
(drops) the older pending pair and counts it.
"""

from __future__ import annotations

import threading
from typing import Generic, TypeVar

T = TypeVar("T")


class NewestWinsSlot(Generic[T]):
    def __init__(self) -> None:
        self._condition = threading.Condition()
        self._item: T | None = None
        self._closed = False
        self.dropped = 0  # pending items replaced by newer ones

    def put(self, item: T) -> bool:
        """Offer an item; returns True if an older pending item was dropped for it."""
        with self._condition:
            dropped = self._item is not None
            if dropped:
                self.dropped += 1
            self._item = item
            self._condition.notify()
            return dropped

    def take(self, timeout: float | None = None) -> T | None:
        """The pending item (removing it), waiting up to ``timeout``; None on timeout or close."""
        with self._condition:
            self._condition.wait_for(lambda: self._item is not None or self._closed, timeout)
            item, self._item = self._item, None
            return None if self._closed else item

    def clear(self) -> None:
        """Discard the pending item without counting it as dropped (a reset, not an overload)."""
        with self._condition:
            self._item = None

    def close(self) -> None:
        """Wake the taker for good: every later ``take`` returns None at once."""
        with self._condition:
            self._closed = True
            self._condition.notify_all()

    @property
    def pending(self) -> int:
        with self._condition:
            return 0 if self._item is None else 1
