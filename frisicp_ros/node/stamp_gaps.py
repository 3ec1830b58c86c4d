"""Data clouds lost on their way to the node, counted from gaps in their header stamps.

A sensor stamps its scans at a steady period; DDS that cannot deliver a large message (a best-effort
stream, or fragments lost under load) leaves a gap of several periods between the stamps that do
arrive. The period is taken as the lower quartile of the recent stamp gaps, which stays the true
period as long as a quarter of the clouds arrive back to back (at 45 % delivery, 45 % do), and each
gap of k periods (rounded, k >= 1.5) counts k - 1 lost clouds. Gaps of more than
:data:`PAUSE_PERIODS` periods are a pause of the sensor (or a replay), not losses; stamps that do
not increase start over. Jitter of up to a quarter period counts nothing.
"""

from __future__ import annotations

from collections import deque

import numpy as np

PAUSE_PERIODS = 20  # a longer gap is a pause (reported as stale data), not lost clouds
_MIN_GAPS = 10  # gaps needed before the period is trusted


class StampGaps:
    def __init__(self, window: int = 100) -> None:
        self._gaps: deque[int] = deque(maxlen=window)  # recent stamp gaps (ns), increasing stamps only
        self._lost: deque[int] = deque(maxlen=window)  # per arrival: clouds lost just before it
        self._last: int | None = None
        self.lost_total = 0

    def add(self, stamp_ns: int) -> None:
        """A data cloud with header stamp ``stamp_ns`` arrived."""
        last, self._last = self._last, stamp_ns
        if last is None or stamp_ns <= last:
            return
        gap = stamp_ns - last
        period = self.period_ns
        lost = 0
        if period is not None and 1.5 * period <= gap <= PAUSE_PERIODS * period:
            lost = round(gap / period) - 1
        self._gaps.append(gap)
        self._lost.append(lost)
        self.lost_total += lost

    @property
    def period_ns(self) -> float | None:
        """The sensor's period (ns) as the stamps show it; None until enough have arrived."""
        if len(self._gaps) < _MIN_GAPS:
            return None
        return float(np.percentile(np.array(self._gaps, dtype=np.float64), 25))

    @property
    def recent(self) -> tuple[int, int]:
        """(lost, expected) over the last arrivals: expected = arrived + lost."""
        lost = sum(self._lost)
        return lost, len(self._lost) + lost
