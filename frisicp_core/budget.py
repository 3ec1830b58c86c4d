"""The time budget of one registration (``RegistrationConfig.budget_seconds``).

A stream has one worker: a registration that runs for seconds (hostile clouds, a cold search on
huge clouds) makes the node drop every newer pair meanwhile. The solver asks a :class:`Deadline`
between correspondence passes (each iteration of a level, each screening pass, each level);
once it has passed, the iterations stop where they are and the result is returned marked
unreliable with the reason :data:`EXCEEDED` (its numbers are what the last pass had: for
diagnosis, not for use). Wall-clock time, since what a stream cares about is latency; a pass in
progress is not interrupted, so the overrun is at most one pass.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

EXCEEDED = "budget exceeded"


@dataclass
class Deadline:
    """``seconds`` after ``start`` (``time.perf_counter()``); None never passes."""

    seconds: float | None
    start: float = field(default_factory=time.perf_counter)
    exceeded: bool = False

    def passed(self) -> bool:
        """True from the first call after the budget ran out (and on every call after it)."""
        if not self.exceeded and self.seconds is not None:
            self.exceeded = time.perf_counter() - self.start > self.seconds
        return self.exceeded

    def remaining(self) -> float | None:
        """Seconds left (None: unbounded), never below 0."""
        if self.seconds is None:
            return None
        return max(0.0, self.seconds - (time.perf_counter() - self.start))

    @property
    def reason(self) -> str:
        """The verdict's reason for a result cut short ('' while within the budget)."""
        if not self.exceeded:
            return ""
        return (
            f"{EXCEEDED}: stopped after {time.perf_counter() - self.start:.3g} s of the"
            f" {self.seconds:g} s budget (budget_seconds)"
        )
