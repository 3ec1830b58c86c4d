"""One run of the bag mode: the pairs of an open bag through the stream loop into JSONL and a
result bag, with a progress bar and a summary on stderr.

Ctrl-C or SIGTERM (``frisicp_ros.bag.stop``), a damaged message, a full disk or a closed results
pipe stop the run; everything registered before stays written (the result bag is finished and
renamed). The exit code says how it ended: 0 the bag was read to its end (rejected and unreliable
pairs are marked in the JSONL and counted in the summary), 1 stopped early by the bag or an
output, 130 interrupted (SIGINT), 143 terminated (SIGTERM).
"""

from __future__ import annotations

import functools
import statistics
import sys
import time
from collections.abc import Callable
from concurrent.futures.process import BrokenProcessPool
from contextlib import AbstractContextManager
from dataclasses import dataclass, field
from typing import Any

from tqdm import tqdm

from frisicp_core.config import InitialGuess
from frisicp_ros.bag.jobs import ordered_map
from frisicp_ros.bag.output import JsonLines, OutputError, ResultBag, pair_record
from frisicp_ros.bag.pairs import BagPair, PairReading
from frisicp_ros.bag.stop import StopRequest
from frisicp_ros.stream.loop import (
    ChunkRegistrar,
    IndependentRegistrar,
    PairMapper,
    SequentialRegistrar,
    in_chunks,
    run_stream,
)
from frisicp_ros.stream.outputs import ALWAYS_PUBLISHED, build_outputs, scaled_frame, tf_message
from frisicp_ros.stream.pipeline import PairOutcome, Registered
from frisicp_ros.stream.settings import PipelineSettings


@dataclass(frozen=True)
class Destinations:
    """Where results go and how the run shows itself."""

    jsonl: str = "-"  # a file, or "-" for stdout
    result_bag: str | None = None  # a new rosbag2 folder with the node's output topics
    prefix: str = "/frisicp"  # namespace of the result bag's topics
    progress: bool = True
    plot: str | None = None  # a PNG of the results over time (frisicp_ros.stream.pictures)


@dataclass
class RunStats:
    started: float = field(default_factory=time.perf_counter)
    pairs: int = 0
    rejected: int = 0
    unreliable: int = 0  # registered, but the result failed the plausibility verdict
    first_unreliable: str = ""
    converged: int = 0
    rms: list[float] = field(default_factory=list)  # of the reliable results
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
        if not outcome.reliable:
            self.unreliable += 1
            self.first_unreliable = self.first_unreliable or f"pair {pair.index}: {outcome.reason}"
            return
        self.rms.append(outcome.result.rms)

    def summary(self, unpaired: int) -> str:
        seconds = time.perf_counter() - self.started
        median = f"{statistics.median(self.rms):.6g}" if self.rms else "n/a"
        rate = f", {self.pairs / seconds:.2f} pairs/s" if seconds > 0 and self.pairs else ""
        text = (
            f"pairs {self.pairs} (rejected {self.rejected}, unreliable {self.unreliable}), "
            f"converged {self.converged}, median RMS {median}, time {seconds:.2f} s{rate}"
        )
        if unpaired:
            text += f"; {unpaired} data clouds found no model"
        if self.unreliable:
            text += (
                f'; {self.unreliable} implausible results are marked "reliable": false and left out'
                f" of the result bag (first: {self.first_unreliable})"
            )
        return text


# With --jobs N > 1 and warm start, pairs go to the workers in chunks of this many consecutive
# pairs; each chunk is warm-started within itself (its first pair starts cold).
WARM_START_CHUNK = 8


def registration_plan(
    settings: PipelineSettings,
    jobs: int,
    interruptible: Callable[[], AbstractContextManager[object]],
    guess: InitialGuess | None = None,
) -> tuple[Any, PairMapper[Any, BagPair], str | None]:
    """(registrar, mapper, notice) for ``jobs`` processes.

    One job: one pipeline for the whole bag, every pair warm-started from the one before, as in
    the node. Several jobs without warm start: independent pairs, exactly the results of one job.
    Several jobs with warm start: chunks of consecutive pairs, warm-started within each chunk;
    the notice says so (results can differ from one job's in the last digits). An initial
    ``guess`` (one job only) steers the first pair; the pairs after it go on as above.
    """
    if guess is not None and jobs != 1:
        raise ValueError("an initial guess steers the first pair of one stream: use one job")
    if jobs == 1:
        one_job = functools.partial(ordered_map, jobs=1, interruptible=interruptible)
        if settings.warm_start or guess is not None:
            registrar: Any = SequentialRegistrar(settings)
            if guess is not None:
                registrar.request_guess(guess)
        else:
            registrar = IndependentRegistrar(settings)
        return registrar, one_job, None
    parallel = functools.partial(ordered_map, jobs=jobs, interruptible=interruptible)
    if not settings.warm_start:
        return IndependentRegistrar(settings), parallel, None
    notice = (
        f"--jobs {jobs}: each worker warm-starts within chunks of {WARM_START_CHUNK} consecutive pairs"
        " (the first of each starts cold); --jobs 1 warm-starts every pair, --no-warm-start none"
    )
    return ChunkRegistrar(settings), in_chunks(parallel, WARM_START_CHUNK), notice


def register_bag(
    reading: PairReading,
    settings: PipelineSettings,
    jobs: int,
    to: Destinations,
    data_count: int,
    guess: InitialGuess | None = None,
) -> int:
    """Register every pair of ``reading``; returns the exit code (see the module docstring).

    SIGINT and SIGTERM stop it as described in ``frisicp_ros.bag.stop``, from before the outputs
    are created until after they are closed.
    """
    with StopRequest() as stop:
        return _register_bag(reading, settings, jobs, to, data_count, stop, guess)


def _register_bag(
    reading: PairReading,
    settings: PipelineSettings,
    jobs: int,
    to: Destinations,
    data_count: int,
    stop: StopRequest,
    guess: InitialGuess | None,
) -> int:
    topics = ALWAYS_PUBLISHED + (("aligned",) if settings.publish_aligned else ())
    results = JsonLines(to.jsonl)
    try:
        result_bag = ResultBag(to.result_bag, to.prefix, topics) if to.result_bag else None
    except OutputError:
        results.close()
        raise
    registrar, mapper, notice = registration_plan(settings, jobs, stop.interruptible, guess)
    if notice:
        print(f"frisicp bag: {notice}", file=sys.stderr)
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
    records: list[dict[str, object]] = []  # for the picture (small: no points)

    def emit(pair: BagPair, outcome: PairOutcome) -> None:
        record = pair_record(pair, outcome)
        results.write(record)
        if to.plot:
            records.append(record)
        if result_bag is not None and isinstance(outcome, Registered) and outcome.reliable:
            child = scaled_frame(outcome.data_frame, settings.tf_child_frame)
            result_bag.write(
                pair.data.bag_ns,
                build_outputs(outcome, pair.data_cloud, result_bag.types, topics),
                tf_message(outcome, child, result_bag.types),
            )
        stats.add(pair, outcome)
        progress.update(pair.data.ordinal + 1 - progress.n)
        stop.check()

    try:
        run_stream(reading, registrar, emit, mapper)
        if reading.stopped is not None:
            stopped, code = reading.stopped, 1
        else:
            progress.update(data_count - progress.n)
    except KeyboardInterrupt:  # StopRequested, or a Ctrl-C outside the main thread
        stopped, code = (stop.description, stop.exit_code) if stop.requested else ("interrupted", 130)
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
    if to.plot and records:
        from frisicp_ros.stream.pictures import stream_picture

        try:
            print(f"frisicp bag: picture {stream_picture(records, to.plot)}", file=sys.stderr)
        except (OSError, ValueError) as err:  # the results are written: a picture failing costs no data
            print(f"frisicp bag: cannot write the picture {to.plot}: {err}", file=sys.stderr)
            code = code or 1
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
