"""One run of the bag mode: the pairs of one or more bags through the stream loop into JSONL and
result bags (the node's topics and ``/tf``) and pictures (``--plot``), with one progress bar
across the batch and summaries on stderr.

The bags are read and paired here, in batch order, as one stream; an executor
(``frisicp_ros.bag.executors``: local processes or a Dask cluster) registers them; their results
are written here, in order, each to its bag's outputs. So a line never depends on what
computed it, and is written exactly once.

Per bag: a bag that cannot be opened (or lacks a topic) is reported and skipped; a bag damaged
part-way, or one a cluster worker cannot read, stops with everything before kept; either way the
batch goes on with the next bag. Ctrl-C or SIGTERM (``frisicp_ros.bag.stop``), a full disk, a
closed results pipe or a lost executor stop the whole run; everything registered before stays
written (result bags are finished and renamed).

The exit code says how it ended: 0 every bag was read to its end (rejected and unreliable pairs
are marked in the JSONL and counted in the summaries), 1 some bag was unreadable or stopped
early, the run was stopped by an output or the executor, or a picture could not be written, 2 no
bag could be read at all, 130 interrupted (SIGINT), 143 terminated (SIGTERM).
"""

from __future__ import annotations

import statistics
import sys
import time
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from tqdm import tqdm

from frisicp_ros.bag.executors import BatchPair, Executor, ExecutorError, Unregistered
from frisicp_ros.bag.locate import BagSource
from frisicp_ros.bag.output import JsonLines, OutputError, ResultBag, pair_record
from frisicp_ros.bag.pairs import BagPair, PairReading
from frisicp_ros.bag.reader import BagError, open_bag, require_pointcloud2_topic
from frisicp_ros.bag.stop import StopRequest
from frisicp_ros.stream.loop import run_stream
from frisicp_ros.stream.outputs import ALWAYS_PUBLISHED, build_outputs, scaled_frame, tf_message
from frisicp_ros.stream.pairing import PairingMode
from frisicp_ros.stream.pipeline import PairOutcome, Registered
from frisicp_ros.stream.settings import PipelineSettings


@dataclass(frozen=True)
class Destinations:
    """Where one bag's results go."""

    jsonl: str = "-"  # a file, or "-" for stdout
    result_bag: str | None = None  # a new rosbag2 folder with the node's output topics
    prefix: str = "/frisicp"  # namespace of the result bag's topics
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
    depth_step_advice: str = ""  # the first advice about the data clouds' depth steps

    def add(self, pair: BagPair, outcome: PairOutcome) -> None:
        self.pairs += 1
        self.last = f"after pair {pair.index} (data cloud at bag time {pair.data.bag_ns} ns)"
        self.register_seconds += outcome.timings.register_seconds
        if not isinstance(outcome, Registered):
            self.rejected += 1
            return
        self.depth_step_advice = self.depth_step_advice or outcome.depth_step_advice
        self.converged += outcome.result.converged
        if not outcome.reliable:
            self.unreliable += 1
            self.first_unreliable = self.first_unreliable or f"pair {pair.index}: {outcome.reason}"
            return
        self.rms.append(outcome.result.rms)

    def summary(self, unpaired: int, wall_time: bool = True) -> str:
        """One line; ``wall_time`` False for a bag of a batch, whose pairs were registered while
        other bags' were written (its registration time is given instead, summed over workers)."""
        seconds = time.perf_counter() - self.started
        median = f"{statistics.median(self.rms):.6g}" if self.rms else "n/a"
        rate = f", {self.pairs / seconds:.2f} pairs/s" if seconds > 0 and self.pairs else ""
        timing = f"time {seconds:.2f} s{rate}" if wall_time else f"registration {self.register_seconds:.2f} s"
        text = (
            f"pairs {self.pairs} (rejected {self.rejected}, unreliable {self.unreliable}), "
            f"converged {self.converged}, median RMS {median}, {timing}"
        )
        if unpaired:
            text += f"; {unpaired} data clouds found no model"
        if self.unreliable:
            text += (
                f'; {self.unreliable} implausible results are marked "reliable": false and left out'
                f" of the result bag (first: {self.first_unreliable})"
            )
        if self.depth_step_advice:
            text += f"; {self.depth_step_advice}"
        return text


@dataclass(frozen=True)
class BagJob:
    """One bag of the batch and where its results go."""

    path: Path
    to: Destinations
    name: str = ""  # how the summaries call it ("" for a run of one bag: no prefix)


class BagRun:
    """One bag's part of the run: opened (surveyed) before, read and written during, reported after."""

    def __init__(self, job: BagJob, settings: PipelineSettings, topics: tuple[str, str]) -> None:
        self.job = job
        self.settings = settings
        self.topics = topics
        self.unreadable: str | None = None  # why it was skipped
        self.source: BagSource | None = None
        self.data_count = 0
        self.offset = 0  # data clouds of the bags before it, for the batch's progress bar
        self.reading: PairReading | None = None
        self.read_error: str | None = None  # opened at the survey, not when read
        self.failed: str | None = None  # why an executor could not register its pairs
        self.cut_short: str | None = None  # why the run stopped while this bag was in hand
        self.stats: RunStats | None = None  # from the moment its outputs exist
        self.results: JsonLines | None = None
        self.result_bag: ResultBag | None = None
        self.records: list[dict[str, object]] = []  # for the picture (small: no points)
        self.picture_failed = False  # --plot could not be written (the results are)
        self.finished = False

    @property
    def label(self) -> str:
        return f"{self.job.name}: " if self.job.name else ""

    def survey(self) -> None:
        """Open the bag, check its topics, count its data clouds; ``unreadable`` says why not."""
        model_topic, data_topic = self.topics
        try:
            with open_bag(self.job.path) as reader:
                for topic in self.topics:
                    require_pointcloud2_topic(reader, topic)
                self.data_count = reader.topics[data_topic].msgcount
            self.source = BagSource.of(self.job.path, model_topic, data_topic)
        except (BagError, OSError) as err:
            self.unreadable = str(err) if isinstance(err, BagError) else f"{self.job.path}: {err}"

    def pairs(self, bag: int) -> Iterator[BatchPair]:
        """The bag's pairs in bag order, until it ends, is damaged, or its registration failed."""
        assert self.source is not None
        try:
            with open_bag(self.job.path) as reader:
                self.reading = PairReading.paired_as(self.settings, reader, *self.topics)
                for pair in self.reading:
                    if self.failed:
                        return
                    yield BatchPair(bag, self.source, pair)
        except BagError as err:
            self.read_error = str(err)

    def open(self) -> None:
        """Create the outputs (a bag without pairs still gets them, empty)."""
        to = self.job.to
        topics = ALWAYS_PUBLISHED + (("aligned",) if self.settings.publish_aligned else ())
        self.stats = RunStats()
        self.results = JsonLines(to.jsonl)
        try:
            self.result_bag = ResultBag(to.result_bag, to.prefix, topics) if to.result_bag else None
        except OutputError:
            self.results.close()
            raise

    def write(self, pair: BagPair, outcome: PairOutcome) -> None:
        assert self.results is not None and self.stats is not None
        record = pair_record(pair, outcome)
        self.results.write(record)
        if self.job.to.plot:
            self.records.append(record)
        if self.result_bag is not None and isinstance(outcome, Registered) and outcome.reliable:
            types = self.result_bag.types
            child = scaled_frame(outcome.data_frame, self.settings.tf_child_frame)
            self.result_bag.write(
                pair.data.bag_ns,
                build_outputs(outcome, pair.data_cloud, types, self.result_bag.topics),
                tf_message(outcome, child, types),
            )
        self.stats.add(pair, outcome)

    @property
    def stopped(self) -> str | None:
        """Why the bag was not read to its end (None: it was)."""
        if self.cut_short or self.failed or self.read_error:
            return self.cut_short or self.failed or self.read_error
        return self.reading.stopped if self.reading is not None else None

    def close(self, stopped: str | None) -> list[str]:
        """Close the outputs; the lines that report the bag (``stopped``: why the run stopped)."""
        self.finished = True
        self.cut_short = stopped
        assert self.results is not None and self.stats is not None
        self.results.close()
        kept = f"{self.stats.pairs} results kept in {'stdout' if self.job.to.jsonl == '-' else self.job.to.jsonl}"
        if self.result_bag is not None:
            kept += f" and {self.result_bag.close()}"
        lines = []
        stopped = self.stopped
        if stopped is not None:
            lines.append(f"{self.label}stopped {self.stats.last}: {stopped}; {kept}")
        unpaired = self.reading.pairer.unpaired_data if self.reading is not None else 0
        lines.append(f"{self.label}{self.stats.summary(unpaired, wall_time=not self.job.name)}")
        if self.stats.pairs == 0 and stopped is None and self.reading is not None:
            lines.append(f"{self.label}no pairs: {no_pairs_hint(self.settings, self.reading)}")
        if self.job.to.plot and self.records:
            lines.append(self.label + self.draw(self.job.to.plot))
        return lines

    def draw(self, path: str) -> str:
        """The picture of the bag's results over time (after its outputs are closed: a picture
        failing costs no data, only the exit code)."""
        from frisicp_ros.stream.pictures import stream_picture

        try:
            return f"picture {stream_picture(self.records, path, self.job.name)}"
        except (OSError, ValueError) as err:
            self.picture_failed = True
            return f"cannot write the picture {path}: {err}"


def register_batch(runs: Sequence[BagRun], executor: Executor, progress: bool) -> int:
    """Register every pair of every surveyed bag of ``runs``; returns the exit code (see the
    module docstring). SIGINT and SIGTERM stop it as described in ``frisicp_ros.bag.stop``, from
    before the outputs are created until after they are closed."""
    with StopRequest() as stop:
        return _register_batch(runs, executor, progress, stop)


def _register_batch(runs: Sequence[BagRun], executor: Executor, show: bool, stop: StopRequest) -> int:
    batch = len(runs) > 1
    readable = [run for run in runs if run.unreadable is None]
    for run in runs:
        if run.unreadable is not None:
            say(f"frisicp bag: {run.label}skipped: {run.unreadable}")
    offset = 0
    for run in readable:
        run.offset, offset = offset, offset + run.data_count
    registrar, mapper, notice = executor.plan(runs[0].settings, stop.interruptible)
    if notice:
        say(f"frisicp bag: {notice}")
    totals = RunStats()
    progress = tqdm(
        total=offset, unit="cloud", desc="registering", file=sys.stderr, disable=not show, dynamic_ncols=True
    )
    current = -1  # the bag whose results are being written

    def advance_to(bag: int) -> None:
        """Finish the bags before ``bag`` (read to their end by now) and open ``bag``'s outputs."""
        nonlocal current
        while current < bag:
            if current >= 0:
                finish(runs[current], None)
            following = runs[current + 1]
            if following.unreadable is None:
                following.open()
                if batch:
                    progress.set_postfix_str(f"bag {current + 2}/{len(runs)} {following.job.name}")
            current += 1

    def finish(run: BagRun, stopped: str | None, bar_open: bool = True) -> None:
        if run.unreadable is not None or run.finished:
            return
        if bar_open and stopped is None and run.stopped is None:  # read to its end
            progress.update(run.offset + run.data_count - progress.n)
        for line in run.close(stopped):
            say(f"frisicp bag: {line}", progress if bar_open else None)

    def emit(item: BatchPair, outcome: PairOutcome | Unregistered) -> None:
        advance_to(item.bag)
        run = runs[item.bag]
        if run.failed:
            return  # a pair of a bag that failed before it: computed in flight, not wanted
        if isinstance(outcome, Unregistered):
            run.failed = outcome.reason
            return
        run.write(item.pair, outcome)
        totals.add(item.pair, outcome)
        progress.update(run.offset + item.pair.data.ordinal + 1 - progress.n)
        stop.check()

    def batch_pairs() -> Iterator[BatchPair]:
        for bag, run in enumerate(runs):
            if run.unreadable is None:
                yield from run.pairs(bag)

    try:
        advance_to(0)  # the first bag's outputs exist before any work, as for a single bag
    except OutputError:
        progress.close()
        executor.close()
        raise
    stopped: str | None = None
    code = 0
    try:
        run_stream(batch_pairs(), registrar, emit, mapper)
        advance_to(len(runs) - 1)
    except KeyboardInterrupt:  # StopRequested, or a Ctrl-C outside the main thread
        stopped, code = (stop.description, stop.exit_code) if stop.requested else ("interrupted", 130)
    except (ExecutorError, OutputError) as err:  # a full disk, a closed pipe: what was written stays
        stopped, code = str(err), 1
    finally:
        last = runs[current] if current >= 0 else None
        if last is not None and stopped is None and last.stopped is None and last.unreadable is None:
            progress.update(last.offset + last.data_count - progress.n)
        progress.close()
        if last is not None and last.unreadable is None and not last.finished:
            finish(last, stopped, bar_open=False)
        elif stopped is not None:  # between two bags (the next one's outputs could not be created)
            say(f"frisicp bag: stopped: {stopped}")
        remark = executor.close()
    if remark:
        say(f"frisicp bag: {remark}")
    if batch:
        say(f"frisicp bag: {batch_summary(runs, totals)}")
    if code:
        return code
    if not readable:
        return 2
    return 1 if any(run.unreadable or run.stopped or run.picture_failed for run in runs) else 0


def batch_summary(runs: Sequence[BagRun], totals: RunStats) -> str:
    complete = [r for r in runs if r.finished and r.stopped is None]
    stopped = [r for r in runs if r.finished and r.stopped is not None]
    unreadable = [r for r in runs if r.unreadable is not None]
    untouched = len(runs) - len(complete) - len(stopped) - len(unreadable)
    unpaired = sum(r.reading.pairer.unpaired_data for r in runs if r.reading is not None)
    parts = [f"{len(complete)} read to the end"]
    for what, group in (("stopped early", stopped), ("unreadable", unreadable)):
        if group:
            parts.append(f"{len(group)} {what} ({', '.join(r.job.name for r in group)})")
    if untouched:
        parts.append(f"{untouched} not started")
    return f"batch of {len(runs)} bags: {', '.join(parts)}; {totals.summary(unpaired)}"


def say(line: str, progress: tqdm | None = None) -> None:
    """A line on stderr, above the progress bar while it runs."""
    if progress is not None:
        progress.write(line, file=sys.stderr)
    else:
        print(line, file=sys.stderr)


def no_pairs_hint(settings: PipelineSettings, reading: PairReading) -> str:
    if reading.model_clouds == 0 or reading.data_clouds == 0:
        return f"{reading.model_clouds} model and {reading.data_clouds} data clouds in the bag"
    if settings.pairing == PairingMode.LATEST_MODEL:
        return "every data cloud came before the first model cloud"
    return (
        f"no model and data header stamps within --sync-tolerance {settings.sync_tolerance} s "
        "(try a larger tolerance, or --pairing latest_model)"
    )
