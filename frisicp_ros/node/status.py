"""What the node reports on /diagnostics, counted without ROS (thread-safe, bounded memory).

Callbacks count inputs, the worker records outcomes, the diagnostics timer takes a
:class:`StatusReport` once per period. Rates are per period; latency percentiles are over the
last ``window`` pairs.

Every pair the worker takes ends in exactly one counter: "registered pairs" (a reliable result,
published), "unreliable results" (registered but implausible: not published), "rejected ..."
(no result) or "publish errors" (an exception while publishing). The level is never OK while the
last pair failed in any of these ways, and ERROR after :data:`ERROR_AFTER_FAILURES` failures in a
row or when the registration worker has stopped. It is WARN, with what to do, when no data cloud
arrived for ``stale_after`` seconds, when ``~/reset`` left no model (a latched map is not sent
again), when the data clouds' stamps show that more than :data:`LOST_SHARE_WARN` of them never
arrived (``stamp_gaps``), and when the data clouds come in coarse depth steps
(``frisicp_ros.stream.depth_check``).
"""

from __future__ import annotations

import threading
import time
from collections import Counter, deque
from dataclasses import dataclass

import numpy as np

from frisicp_ros.node.stamp_gaps import StampGaps
from frisicp_ros.stream.pipeline import PairOutcome, Registered, Rejected

OK, WARN, ERROR = 0, 1, 2  # diagnostic_msgs/DiagnosticStatus levels
LOST_SHARE_WARN = 0.05  # share of the recent data clouds lost in transport that makes a WARN
_MIN_LOST = 3  # ... and at least this many (one lost cloud among 20 is no pattern)
# The timing split of registered pairs, as averaged for /diagnostics.
_SPLIT = ("conversion", "down-sampling", "registration", "registration CPU", "output")
ERROR_AFTER_FAILURES = 3  # consecutive failed pairs (rejected, unreliable, error) before ERROR


@dataclass(frozen=True)
class StatusReport:
    level: int
    message: str
    values: dict[str, str]


class NodeStatus:
    def __init__(self, window: int = 200, stale_after: float = 3.0, fix_for_lost_scans: str = "") -> None:
        self._lock = threading.Lock()
        self._stale_after = stale_after
        self._fix_for_lost_scans = fix_for_lost_scans
        self._last_data_at: float | None = None  # time.monotonic() of the last data cloud
        self._stamp_gaps = StampGaps()
        self._reset_since_registered = False  # ~/reset and no registered pair since
        self._guess = ""  # what became of the last initial guess
        self._tf = "off"
        self._inputs: Counter[str] = Counter()  # since the last report
        self._rejected: Counter[str] = Counter()  # totals by 'model' | 'data' | 'pair'
        self._last_rejection = ""
        self._unreliable = 0
        self._last_unreliable = ""
        self._publish_errors = 0
        self._last_error = ""
        self._consecutive_failures = 0
        self._last_failure = ""  # what the level message says while failures go on
        self._worker_stopped: str | None = None
        self._registered = 0
        self._registered_since_report = 0
        self._last_registered: Registered | None = None
        self._depth_steps = "not checked"  # the data clouds' depth steps, as last found
        self._depth_step_advice = ""
        self._latency: deque[float] = deque(maxlen=window)
        self._transport: deque[float] = deque(maxlen=window)  # data clouds: publication -> DDS receipt
        self._callback_delay: deque[float] = deque(maxlen=window)  # DDS receipt -> callback
        # Per registered pair: conversion, down-sampling, registration (wall, CPU), outputs.
        self._seconds: dict[str, deque[float]] = {key: deque(maxlen=window) for key in _SPLIT}
        self._reported_at = time.monotonic()

    def mark_started(self) -> None:
        """Work (re)starts: staleness counts from the next data cloud."""
        with self._lock:
            self._last_data_at = None

    def count_data(self, stamp_ns: int) -> None:
        """A data cloud stamped ``stamp_ns`` arrived now (for staleness and lost clouds)."""
        with self._lock:
            self._last_data_at = time.monotonic()
            self._stamp_gaps.add(stamp_ns)

    def record_reset(self) -> None:
        with self._lock:
            self._reset_since_registered = True

    def record_guess(self, what: str) -> None:
        with self._lock:
            self._guess = what

    def set_tf(self, what: str) -> None:
        with self._lock:
            self._tf = what

    def count_input(self, topic: str, transport: float | None = None, callback: float | None = None) -> None:
        """A cloud arrived on ``topic``: ``transport`` seconds from its publication to its receipt by
        DDS (the publisher's clock), then ``callback`` seconds until its callback ran."""
        with self._lock:
            self._inputs[topic] += 1
            if topic == "data" and transport is not None and callback is not None:
                self._transport.append(transport)
                self._callback_delay.append(callback)

    def record(self, outcome: PairOutcome, latency: float | None, publish_seconds: float) -> None:
        """One processed pair; ``latency`` from data receipt to publication (None in replay)."""
        with self._lock:
            if isinstance(outcome, Rejected):
                self._rejected[outcome.input] += 1
                self._last_rejection = outcome.reason
                self._failed(f"pair rejected: {outcome.reason}")
                return
            self._depth_steps = "none found" if outcome.depth_steps is None else str(outcome.depth_steps)
            self._depth_step_advice = outcome.depth_step_advice
            if not outcome.reliable:
                scale = outcome.result.similarity.scale
                self._unreliable += 1
                self._last_unreliable = f"scale {scale:.6g}: {outcome.reason}"
                self._failed(f"result implausible, not published (scale {scale:.6g}): {outcome.reason}")
                return
            self._consecutive_failures = 0
            self._reset_since_registered = False
            self._registered += 1
            self._registered_since_report += 1
            self._last_registered = outcome
            if latency is not None:
                self._latency.append(latency)
            timings = outcome.timings
            for key, seconds in zip(
                _SPLIT,
                (
                    timings.convert_seconds,
                    timings.downsample_seconds,
                    timings.register_seconds,
                    timings.register_cpu_seconds,
                    publish_seconds,
                ),
                strict=True,
            ):
                self._seconds[key].append(seconds)

    def record_error(self, error: str) -> None:
        """A pair whose publication raised ``error``; the worker goes on with the next pair."""
        with self._lock:
            self._publish_errors += 1
            self._last_error = error
            self._failed(f"publication failed: {error}")

    def record_worker_stopped(self, error: str) -> None:
        """The registration worker is gone (a bug): nothing will be registered any more."""
        with self._lock:
            if self._worker_stopped is None:  # the first reason is the one that explains
                self._worker_stopped = error

    def _failed(self, what: str) -> None:
        self._consecutive_failures += 1
        self._last_failure = what

    def report(
        self, dropped_pairs: int, unpaired_data: int, has_model: bool, guess_pending: bool = False
    ) -> StatusReport:
        with self._lock:
            now = time.monotonic()
            lost, expected = self._stamp_gaps.recent
            sensor_period = self._stamp_gaps.period_ns
            period = max(now - self._reported_at, 1e-9)
            values = {
                "model rate (Hz)": f"{self._inputs['model'] / period:.2f}",
                "data rate (Hz)": f"{self._inputs['data'] / period:.2f}",
                "output rate (Hz)": f"{self._registered_since_report / period:.2f}",
                "registered pairs": str(self._registered),
                "dropped pairs": str(dropped_pairs),
                "unpaired data clouds": str(unpaired_data),
                "rejected model clouds": str(self._rejected["model"]),
                "rejected data clouds": str(self._rejected["data"]),
                "rejected pairs": str(self._rejected["pair"]),
                "last rejection": self._last_rejection,
                "unreliable results": str(self._unreliable),
                "last unreliable result": self._last_unreliable,
                "publish errors": str(self._publish_errors),
                "last publish error": self._last_error,
                "data clouds lost (stamp gaps)": str(self._stamp_gaps.lost_total),
                "data clouds lost, recent": f"{lost} of {expected}",
                "data period (ms)": "unknown" if sensor_period is None else f"{sensor_period * 1e-6:.1f}",
                "seconds since data": (
                    "never" if self._last_data_at is None else f"{now - self._last_data_at:.1f}"
                ),
                "initial guess": ("pending: " if guess_pending else "") + (self._guess or "none"),
                "/tf": self._tf,
                "data depth steps": self._depth_steps,
            }
            values.update(self._latency_values())
            values.update(self._result_values())
            self._inputs.clear()
            self._registered_since_report = 0
            self._reported_at = now
            level, message = self._level(has_model, now, lost, expected, sensor_period)
            return StatusReport(level, message, values)

    def _latency_values(self) -> dict[str, str]:
        if not self._seconds["registration"]:
            return {}
        values = {}
        if self._latency:
            p50, p95, worst = np.percentile(np.array(self._latency) * 1e3, [50, 95, 100])
            values = {
                "latency p50 (ms)": f"{p50:.1f}",
                "latency p95 (ms)": f"{p95:.1f}",
                "latency max (ms)": f"{worst:.1f}",
            }
        if self._callback_delay:
            transport = np.percentile(np.array(self._transport) * 1e3, [50, 95])
            callback = np.percentile(np.array(self._callback_delay) * 1e3, [50, 95, 100])
            values.update(
                {
                    "data transport p50 (ms)": f"{transport[0]:.1f}",
                    "data transport p95 (ms)": f"{transport[1]:.1f}",
                    "callback delay p50 (ms)": f"{callback[0]:.2f}",
                    "callback delay p95 (ms)": f"{callback[1]:.2f}",
                    "callback delay max (ms)": f"{callback[2]:.2f}",
                }
            )
        mean = {key: float(np.mean(seconds)) for key, seconds in self._seconds.items()}
        core = mean["registration"]
        node = mean["conversion"] + mean["down-sampling"] + mean["output"]

        def share(seconds: float) -> str:
            return f"{seconds / core:.4f}" if core > 0 else "nan"

        values.update(
            {
                "conversion mean (ms)": f"{mean['conversion'] * 1e3:.2f}",
                "down-sampling mean (ms)": f"{mean['down-sampling'] * 1e3:.2f}",
                "registration mean (ms)": f"{core * 1e3:.1f}",
                "registration CPU mean (ms)": f"{mean['registration CPU'] * 1e3:.1f}",
                "output mean (ms)": f"{mean['output'] * 1e3:.2f}",
                "node overhead mean (ms)": f"{node * 1e3:.2f}",
                "conversion / registration": share(mean["conversion"]),
                "down-sampling / registration": share(mean["down-sampling"]),
                "output / registration": share(mean["output"]),
                "node overhead / registration": share(node),
            }
        )
        return values

    def _result_values(self) -> dict[str, str]:
        outcome = self._last_registered
        if outcome is None:
            return {}
        result = outcome.result
        return {
            "last rms": f"{result.rms:.6g}",
            "last scale": f"{result.similarity.scale:.6g}",
            "last iterations": str(sum(result.iterations)),
            "last converged": str(result.converged),
            "last stamp (ns)": str(outcome.stamp_ns),
            "warm started": str(outcome.warm_started),
            "last depth averaged (data, model voxels)": (
                "no"
                if result.depth_averaged is None
                else ", ".join(f"{e:.3g}" for e in result.depth_averaged)
            ),
            **_uncertainty_values(outcome),
        }

    def _level(
        self, has_model: bool, now: float, lost: int, expected: int, sensor_period: float | None
    ) -> tuple[int, str]:
        if self._worker_stopped is not None:
            return ERROR, f"registration worker stopped: {self._worker_stopped}"
        failures = self._consecutive_failures
        if failures >= ERROR_AFTER_FAILURES:
            return ERROR, f"last {failures} pairs failed; last: {self._last_failure}"
        if self._last_data_at is not None and now - self._last_data_at > self._stale_after:
            return WARN, f"no data for {now - self._last_data_at:.0f} s (stale_after {self._stale_after:g} s)"
        if failures:
            return WARN, f"last {self._last_failure}"
        if self._reset_since_registered and not has_model:
            return WARN, (
                "no model since ~/reset: a latched map is not sent again; republish the model"
                " (or restart its publisher)"
            )
        if lost >= _MIN_LOST and lost > LOST_SHARE_WARN * expected:
            sensor = "" if sensor_period is None else f", sensor period {sensor_period * 1e-6:.0f} ms"
            return WARN, (
                f"{lost} of the last {expected} data clouds never arrived (gaps in their header"
                f" stamps{sensor}); {self._fix_for_lost_scans}"
            )
        if self._last_registered is None or self._reset_since_registered:
            return WARN, "waiting for clouds" if has_model else "waiting for a model cloud"
        if self._depth_step_advice:
            return WARN, self._depth_step_advice
        return OK, "registering"


def _uncertainty_values(outcome: Registered) -> dict[str, str]:
    """The last result's 1-sigma uncertainty (frisicp_core.uncertainty), when estimated."""
    uncertainty = outcome.result.uncertainty
    if uncertainty is None:
        return {"last uncertainty": "not estimated"}
    return {
        "last scale sigma (relative)": f"{uncertainty.scale:.3g}",
        "last rotation sigma (deg)": f"{uncertainty.rotation_deg:.3g}",
        "last translation sigma": f"{uncertainty.translation:.3g}",
    }
