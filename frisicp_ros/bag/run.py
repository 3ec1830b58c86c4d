"""One run of the bag mode: the pairs of an open bag through the stream loop into JSONL and a
result bag, with a progress bar and a summary on stderr.

Ctrl-C, a damaged message, a full disk or a closed results pipe stop the run; everything
registered before stays written (the result bag is finished and renamed). The exit code says
how it ended: 0 done, 1 stopped early by the bag or an output, 130 interrupted.
"""

from __future__ import annotations

import functools
import signal
import statistics
import sys
import threading
import time
from collections.abc import Callable
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass, field
from types import FrameType

from tqdm import tqdm

from frisicp_ros.bag.jobs import ordered_map
from frisicp_ros.bag.output import JsonLines, OutputError, ResultBag, pair_record
from frisicp_ros.bag.pairs import BagPair, PairReading
from frisicp_ros.stream.loop import IndependentRegistrar, Registrar, SequentialRegistrar, run_stream
from frisicp_ros.stream.outputs import ALWAYS_PUBLISHED, build_outputs
from frisicp_ros.stream.pipeline import PairOutcome, Registered
from frisicp_ros.stream.settings import PipelineSettings


@dataclass(frozen=True)
class Destinations:
    """Where results go and how the run shows itself."""

    jsonl: str = "-"  # a file, or "-" for stdout
    result_bag: str | None = None  # a new rosbag2 folder with the node's output topics
    prefix: str = "/frisicp"  # namespace of the result bag's topics
    progress: bool = True


@dataclass
class RunStats:
    started: float = field(default_factory=time.perf_counter)
    pairs: int = 0
    rejected: int = 0
    converged: int = 0
    rms: list[float] = field(default_factory=list)
    register_seconds: float = 0.0
    last: str = "before the first pair"

    def add(self, pair: BagPair, outcome: PairOutcome) -> None:
        self.pairs += 1
        self.last = f"after pair {pair.index} (data cloud at bag time {pair.data.bag_ns} ns)"
        self.register_seconds += outcome.timings.register_seconds
        if not isinstance(outcome, Registered):
            self.rejected += 1
            return
        self.converged += outcome.result.converged
        self.rms.append(outcome.result.rms)

    def summary(self, unpaired: int) -> str:
        seconds = time.perf_counter() - self.started
        median = f"{statistics.median(self.rms):.6g}" if self.rms else "n/a"
        rate = f", {self.pairs / seconds:.2f} pairs/s" if seconds > 0 and self.pairs else ""
        text = (
            f"pairs {self.pairs} (rejected {self.rejected}), converged {self.converged}, "
            f"median RMS {median}, time {seconds:.2f} s{rate}"
        )
        if unpaired:
            text += f"; {unpaired} data clouds found no model"
        return text


class InterruptRequest:
    """Ctrl-C as a request: the pair in hand is finished and written to every output (so the
    JSONL and the result bag hold the same pairs), then the run stops. A second Ctrl-C stops at
    once. Only in the main thread, where Python delivers signals; elsewhere Ctrl-C is as usual.
    """

    def __init__(self) -> None:
        self.requested = False
        self._previous: Callable[[int, FrameType | None], object] | int | None = None

    def __enter__(self) -> InterruptRequest:
        if threading.current_thread() is threading.main_thread():
            self._previous = signal.signal(signal.SIGINT, self._on_interrupt)
        return self

    def _on_interrupt(self, signum: int, frame: object) -> None:
        if self.requested:
            raise KeyboardInterrupt
        self.requested = True

    def __exit__(self, *exc_info: object) -> None:
        if self._previous is not None:
            signal.signal(signal.SIGINT, self._previous)


def registrar_for(settings: PipelineSettings, jobs: int) -> Registrar[BagPair]:
    """Warm start chains each pair to the one before (one pipeline, one process); without it
    every pair gets a fresh pipeline, so ``--jobs N`` gives exactly the results of ``--jobs 1``."""
    if settings.warm_start:
        if jobs > 1:
            raise ValueError("warm start chains every pair to the one before it: it needs one job")
        return SequentialRegistrar(settings)
    return IndependentRegistrar(settings)


def register_bag(
    reading: PairReading, settings: PipelineSettings, jobs: int, to: Destinations, data_count: int
) -> int:
    """Register every pair of ``reading``; returns the exit code (see the module docstring)."""
    topics = ALWAYS_PUBLISHED + (("aligned",) if settings.publish_aligned else ())
    results = JsonLines(to.jsonl)
    result_bag = ResultBag(to.result_bag, to.prefix, topics) if to.result_bag else None
    stats = RunStats()
    progress = tqdm(
        total=data_count,
        unit="cloud",
        desc="registering",
        file=sys.stderr,
        disable=not to.progress,
        dynamic_ncols=True,
    )
    stopped: str | None = None
    code = 0

    def emit(pair: BagPair, outcome: PairOutcome) -> None:
        results.write(pair_record(pair, outcome))
        if result_bag is not None and isinstance(outcome, Registered):
            result_bag.write(
                pair.data.bag_ns, build_outputs(outcome, pair.data_cloud, result_bag.types, topics)
            )
        stats.add(pair, outcome)
        progress.update(pair.data.ordinal + 1 - progress.n)
        if interrupt.requested:
            raise KeyboardInterrupt

    try:
        with InterruptRequest() as interrupt:
            mapper = functools.partial(ordered_map, jobs=jobs)
            run_stream(reading, registrar_for(settings, jobs), emit, mapper)
        if reading.stopped is not None:
            stopped, code = reading.stopped, 1
        else:
            progress.update(data_count - progress.n)
    except KeyboardInterrupt:
        stopped, code = "interrupted", 130
    except BrokenProcessPool:
        stopped, code = "a worker process died (out of memory?)", 1
    except OutputError as err:  # a full disk, a closed pipe: what was written stays
        stopped, code = str(err), 1
    finally:
        progress.close()
        results.close()
    kept = f"{stats.pairs} results kept in {'stdout' if to.jsonl == '-' else to.jsonl}"
    if result_bag is not None:
        written = result_bag.close()
        kept += f" and {written}"
    if stopped is not None:
        print(f"frisicp bag: stopped {stats.last}: {stopped}; {kept}", file=sys.stderr)
    print(f"frisicp bag: {stats.summary(reading.pairer.unpaired_data)}", file=sys.stderr)
    if stats.pairs == 0 and stopped is None:
        print(f"frisicp bag: no pairs: {no_pairs_hint(settings, reading)}", file=sys.stderr)
    return code


def no_pairs_hint(settings: PipelineSettings, reading: PairReading) -> str:
    if reading.model_clouds == 0 or reading.data_clouds == 0:
        return f"{reading.model_clouds} model and {reading.data_clouds} data clouds in the bag"
    if settings.pairing == "latest_model":
        return "every data cloud came before the first model cloud"
    return (
        f"no model and data header stamps within --sync-tolerance {settings.sync_tolerance} s "
        "(try a larger tolerance, or --pairing latest_model)"
    )
