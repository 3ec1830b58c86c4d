"""What runs the registrations of a batch: this machine's processes, or a Dask cluster.

An executor turns the settings into a *plan*: the registrar, the pair mapper that applies it
(``frisicp_ros.stream.loop``) and a notice for the user. Everything else (reading and pairing the
bags, writing results in bag order, progress, summaries, stopping) is one code path above the
executors (``frisicp_ros.bag.run``), so the JSONL lines do not depend on what computed them.

Both executors see the pairs of all bags as one stream of :class:`BatchPair` in batch order.
Warm start never crosses a bag: ``--jobs 1`` gives each bag its own sequential pipeline, and
chunks (``--jobs N``, the cluster) are cut per bag from its first pair. A chunk warm-started
within itself gives the same numbers on a local process and on a cluster worker.

A pair an executor could not register (its bag unreadable on a cluster worker, a task lost to
dying workers) comes back as :class:`Unregistered`: the run stops that bag, says why, and goes
on with the next. :class:`ExecutorError` stops the whole run (a local worker process died, the
scheduler is gone).
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Generator, Iterable, Sequence
from concurrent.futures.process import BrokenProcessPool
from contextlib import AbstractContextManager
from dataclasses import dataclass
from typing import Any, NamedTuple, Protocol

from frisicp_core import InitialGuess
from frisicp_ros.bag.jobs import ordered_map
from frisicp_ros.bag.locate import BagSource
from frisicp_ros.bag.pairs import BagPair, PlainCloud
from frisicp_ros.stream.loop import (
    ChunkRegistrar,
    IndependentRegistrar,
    PairMapper,
    SequentialRegistrar,
    in_chunks,
)
from frisicp_ros.stream.pipeline import PairOutcome
from frisicp_ros.stream.settings import PipelineSettings

# With warm start, pairs go to parallel workers in chunks of this many consecutive pairs of one
# bag; each chunk is warm-started within itself (its first pair starts cold). Cluster tasks are
# such chunks with or without warm start (fewer, larger tasks: less scheduling per pair).
WARM_START_CHUNK = 8

Interruptible = Callable[[], AbstractContextManager[object]]


@dataclass(frozen=True)
class BatchPair:
    """A pair of the batch: which bag (its position in the batch), where it is, the pair itself."""

    bag: int
    source: BagSource
    pair: BagPair

    @property
    def model_cloud(self) -> PlainCloud:
        return self.pair.model_cloud

    @property
    def data_cloud(self) -> PlainCloud:
        return self.pair.data_cloud


@dataclass(frozen=True)
class Unregistered:
    """A pair that was not registered, and why (nothing about the pair itself: its bag or task)."""

    reason: str


class ExecutorError(Exception):
    """The executor cannot register anything any more; the message says why."""


class Plan(NamedTuple):
    registrar: Any
    mapper: PairMapper[Any, BatchPair]
    notice: str | None


class Executor(Protocol):
    def plan(self, settings: PipelineSettings, interruptible: Interruptible) -> Plan: ...

    def close(self) -> str | None:
        """Release what the executor holds; returns a closing remark for the user (or None)."""
        ...


class SequentialPerBag:
    """``--jobs 1`` with warm start or an initial guess: one pipeline per bag, each pair
    warm-started from the one before it in the same bag (each bag starts cold, as if registered
    alone). A ``guess`` steers the first pair of every bag (a run of one bag with it gives the
    same lines); tracking goes on from that pair's result."""

    def __init__(self, settings: PipelineSettings, guess: InitialGuess | None = None) -> None:
        self.settings = settings
        self.guess = guess
        self._bag: int | None = None
        self._registrar = SequentialRegistrar(settings)

    def __call__(self, item: BatchPair) -> PairOutcome | None:
        if item.bag != self._bag:
            self._bag, self._registrar = item.bag, SequentialRegistrar(self.settings)
            if self.guess is not None:
                self._registrar.request_guess(self.guess)
        return self._registrar(item)


@dataclass(frozen=True)
class EachPair:
    """A chunk of independent pairs: a fresh pipeline for each (no warm start), picklable."""

    registrar: IndependentRegistrar

    def __call__(self, chunk: Sequence[Any]) -> list[PairOutcome]:
        return [self.registrar(pair) for pair in chunk]


def chunk_registrar(settings: PipelineSettings) -> ChunkRegistrar | EachPair:
    """What registers one chunk: warm-started within it, or every pair on its own."""
    return ChunkRegistrar(settings) if settings.warm_start else EachPair(IndependentRegistrar(settings))


def chunk_notice(who: str) -> str:
    return (
        f"{who}: each worker warm-starts within chunks of {WARM_START_CHUNK} consecutive pairs"
        " (the first of each starts cold); --jobs 1 warm-starts every pair, --no-warm-start none"
    )


def per_bag_chunks(mapper: Callable[..., Any]) -> PairMapper[Any, BatchPair]:
    """``mapper`` over chunks of consecutive pairs, cut per bag."""
    return in_chunks(mapper, WARM_START_CHUNK, stream_of=lambda item: item.bag)


@dataclass(frozen=True)
class LocalProcesses:
    """``--jobs N``: this machine; one job runs in this process, N > 1 in N worker processes.
    An initial ``guess`` (one job only) steers each bag's first pair."""

    jobs: int
    guess: InitialGuess | None = None

    def __post_init__(self) -> None:
        if self.guess is not None and self.jobs != 1:
            # Chunks of parallel workers start blind, exactly where a guess is needed.
            raise ValueError("an initial guess steers the first pair of one stream: use one job")

    def plan(self, settings: PipelineSettings, interruptible: Interruptible) -> Plan:
        """One job: every pair of a bag warm-started from the one before (or from the guess),
        as in the node. Several jobs without warm start: independent pairs, exactly the results
        of one job. Several jobs with warm start: chunks warm-started within themselves; the
        notice says so (results can differ from one job's in the last digits)."""
        mapper = _pool_loss_is_fatal(
            functools.partial(ordered_map, jobs=self.jobs, interruptible=interruptible)
        )
        if self.jobs == 1 and (settings.warm_start or self.guess is not None):
            return Plan(SequentialPerBag(settings, self.guess), mapper, None)
        if not settings.warm_start:
            return Plan(IndependentRegistrar(settings), mapper, None)
        return Plan(ChunkRegistrar(settings), per_bag_chunks(mapper), chunk_notice(f"--jobs {self.jobs}"))

    def close(self) -> str | None:
        return None


def _pool_loss_is_fatal(mapper: Callable[[Any, Iterable[Any]], Generator[Any, None, None]]) -> Any:
    def mapped(register: Any, items: Iterable[Any]) -> Generator[Any, None, None]:
        try:
            yield from mapper(register, items)
        except BrokenProcessPool:
            raise ExecutorError("a worker process died (out of memory?)") from None

    return mapped
