"""Which model cloud each data cloud is registered against. Pure Python, no ROS.

The node feeds it from its subscription callbacks; the offline bag mode feeds it in bag order.
Items are opaque (messages, usually); only the stamps (integer nanoseconds) are looked at.

- ``latest_model`` (map-to-scan): each data cloud is paired with the newest model seen so far;
  data arriving before any model is dropped (counted in ``unpaired_data``).
- ``synchronized`` (two sensors): a data cloud pairs with the model whose stamp is closest
  within ``tolerance_sec``. Whichever of the two arrives second completes the pair, so
  ``add_model`` can return a pair too. Unmatched clouds wait in short buffers
  (``buffer_size`` each, oldest dropped) and anything older than a completed pair is discarded,
  because pairs must come out in stamp order.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Sequence
from enum import Enum
from typing import Generic, TypeVar

ModelT = TypeVar("ModelT")
DataT = TypeVar("DataT")


class PairingMode(str, Enum):
    """How data clouds find their model (module doc); the values are the ``pairing`` parameter's."""

    LATEST_MODEL = "latest_model"
    SYNCHRONIZED = "synchronized"


PAIRING_MODES: tuple[str, ...] = tuple(mode.value for mode in PairingMode)


class Pairer(Generic[ModelT, DataT]):
    def __init__(
        self, mode: str = PairingMode.LATEST_MODEL.value, tolerance_sec: float = 0.05, buffer_size: int = 10
    ) -> None:
        if buffer_size < 1:
            raise ValueError(f"buffer_size must be >= 1, got {buffer_size}")
        self._buffer_size = buffer_size
        self._models: deque[tuple[int, ModelT]] = deque()
        self._data: deque[tuple[int, DataT]] = deque(maxlen=buffer_size)
        self.unpaired_data = 0  # data clouds that found no model (dropped)
        self.mode = PairingMode.LATEST_MODEL.value
        self.tolerance_ns = 0
        self.reconfigure(mode, tolerance_sec)

    def reconfigure(self, mode: str, tolerance_sec: float) -> None:
        """Change the mode or tolerance at run time, keeping what was received.

        The stored models stay (a latched map is published once: dropping it would leave every
        later data cloud unanswered), and so does the counter. Data clouds waiting for a
        synchronized partner are dropped (counted) when switching to latest_model, which never
        pairs a data cloud with a later model.
        """
        if mode not in PAIRING_MODES:
            raise ValueError(f"pairing mode must be one of {', '.join(PAIRING_MODES)}, got {mode!r}")
        if not tolerance_sec >= 0:
            raise ValueError(f"tolerance_sec must be >= 0, got {tolerance_sec}")
        self.mode = mode
        self.tolerance_ns = round(tolerance_sec * 1e9)
        # A deque with maxlen keeps the newest items: latest_model keeps the newest model.
        self._models = deque(
            self._models, maxlen=1 if mode == PairingMode.LATEST_MODEL else self._buffer_size
        )
        if mode == PairingMode.LATEST_MODEL:
            self.unpaired_data += len(self._data)
            self._data.clear()

    @property
    def latest_model(self) -> ModelT | None:
        return self._models[-1][1] if self._models else None

    def reset(self) -> None:
        """Forget every stored model and pending data cloud (the counter is kept)."""
        self._models.clear()
        self._data.clear()

    def add_model(self, stamp_ns: int, item: ModelT) -> list[tuple[ModelT, DataT]]:
        """Store a model; in synchronized mode, return the pair it completes (if any)."""
        if self.mode == PairingMode.LATEST_MODEL:
            self._models.append((stamp_ns, item))
            return []
        match = _closest(self._data, stamp_ns, self.tolerance_ns)
        if match is None:
            self._models.append((stamp_ns, item))
            return []
        data_stamp, data_item = self._data[match]
        self._discard_up_to(data_stamp, stamp_ns, data_was_buffered=True)
        return [(item, data_item)]

    def add_data(self, stamp_ns: int, item: DataT) -> list[tuple[ModelT, DataT]]:
        """Return the pair(s) this data cloud completes: ``[(model_item, data_item)]`` or ``[]``."""
        if self.mode == PairingMode.LATEST_MODEL:
            if not self._models:
                self.unpaired_data += 1
                return []
            return [(self._models[-1][1], item)]
        match = _closest(self._models, stamp_ns, self.tolerance_ns)
        if match is None:
            if len(self._data) == self._data.maxlen:
                self.unpaired_data += 1  # the oldest pending one falls out
            self._data.append((stamp_ns, item))
            return []
        model_stamp, model_item = self._models[match]
        self._discard_up_to(stamp_ns, model_stamp, data_was_buffered=False)
        return [(model_item, item)]

    def _discard_up_to(self, data_stamp: int, model_stamp: int, data_was_buffered: bool) -> None:
        """Drop buffered clouds not newer than a completed pair (they can no longer pair in order)."""
        while self._models and self._models[0][0] <= model_stamp:
            self._models.popleft()
        dropped = 0
        while self._data and self._data[0][0] <= data_stamp:
            self._data.popleft()
            dropped += 1
        self.unpaired_data += dropped - (1 if data_was_buffered else 0)


def _closest(buffer: Sequence[tuple[int, object]], stamp_ns: int, tolerance_ns: int) -> int | None:
    """Index of the buffered stamp nearest to ``stamp_ns`` within the tolerance, or None."""
    best, best_gap = None, tolerance_ns
    for index, (stamp, _) in enumerate(buffer):
        gap = abs(stamp - stamp_ns)
        if gap <= best_gap:
            best, best_gap = index, gap
    return best
