"""The one stream loop (pair -> process -> emit) of the node, its bag replay and ``frisicp bag``.

:func:`run_stream` takes pairs, registers each with a *registrar* and hands the outcome to an
``emit`` callback, in pair order. Two registrars:

- :class:`SequentialRegistrar` owns one :class:`RegistrationPipeline` (warm start, cached model,
  frames) and must be called from one thread only. Other threads (parameter callbacks, the reset
  service) *request* new settings or a reset; the requests are applied by the owning thread
  between two pairs, as the pipeline's one-thread rule demands. A pair during which a reset was
  requested is dropped (its result belongs to the old state).
- :class:`IndependentRegistrar` gives every pair a fresh pipeline: results do not depend on the
  order or on which process computed them, so ``frisicp bag --jobs N`` can map it over worker
  processes (it pickles).
- :class:`ChunkRegistrar` registers a chunk of consecutive pairs with one fresh pipeline, each
  pair warm-started from the one before it within the chunk: ``frisicp bag --jobs N`` with warm
  start maps it over chunks (:func:`in_chunks`), so the workers keep most of the warm start's
  benefit while the chunks run in parallel.
"""

from __future__ import annotations

import itertools
import threading
from collections.abc import Callable, Generator, Iterable, Iterator, Sequence
from contextlib import closing
from dataclasses import dataclass
from typing import Protocol, TypeVar

from frisicp_core import InitialGuess, Similarity
from frisicp_ros.stream.messages import PointCloud2Like
from frisicp_ros.stream.pipeline import PairOutcome, RegistrationPipeline
from frisicp_ros.stream.settings import PipelineSettings


class CloudPair(Protocol):
    """A (model, data) pair of PointCloud2-like messages, plus whatever the emitter needs."""

    @property
    def model_cloud(self) -> PointCloud2Like: ...

    @property
    def data_cloud(self) -> PointCloud2Like: ...


PairT = TypeVar("PairT", bound=CloudPair)
RegistrarT = TypeVar("RegistrarT")
Registrar = Callable[[PairT], "PairOutcome | None"]
# (pair, outcome) in pair order; outcome None: the registrar dropped the pair (a reset came).
RegisteredPairs = Generator[tuple[PairT, "PairOutcome | None"], None, None]
# Maps a registrar over pairs, yielding (pair, outcome) in pair order: serially in this thread,
# or over worker processes (frisicp_ros.bag.jobs.ordered_map), pair by pair or in chunks.
PairMapper = Callable[[RegistrarT, Iterable[PairT]], RegisteredPairs[PairT]]


def serial_map(register: Registrar[PairT], pairs: Iterable[PairT]) -> RegisteredPairs[PairT]:
    for pair in pairs:
        yield pair, register(pair)


def run_stream(
    pairs: Iterable[PairT],
    register: RegistrarT,
    emit: Callable[[PairT, PairOutcome], None],
    mapper: PairMapper[RegistrarT, PairT],
) -> None:
    """Register every pair and emit its outcome, in pair order, until ``pairs`` ends.

    ``mapper`` applies ``register`` (``serial_map`` for a per-pair registrar in this thread).
    ``emit`` runs in the calling thread; an exception in it (or a KeyboardInterrupt) stops the
    loop and closes the mapper, which cancels work not yet started.
    """
    with closing(mapper(register, pairs)) as registered:
        for pair, outcome in registered:
            if outcome is not None:
                emit(pair, outcome)


ChunkMapper = Callable[
    ["ChunkRegistrar", Iterable[list[PairT]]],
    Generator[tuple[list[PairT], list[PairOutcome]], None, None],
]


def in_chunks(
    mapper: ChunkMapper[PairT], size: int, stream_of: Callable[[PairT], object] | None = None
) -> PairMapper[ChunkRegistrar, PairT]:
    """A pair mapper that hands ``mapper`` chunks of ``size`` consecutive pairs.

    With ``stream_of``, pairs of several streams (the bags of a batch) follow each other and a
    chunk never spans two: each stream is chunked from its own first pair, as if alone.
    """

    def mapped(register: ChunkRegistrar, pairs: Iterable[PairT]) -> RegisteredPairs[PairT]:
        chunks = mapper(register, _batched(pairs, size, stream_of))
        with closing(chunks):
            for chunk, outcomes in chunks:
                yield from zip(chunk, outcomes, strict=True)

    return mapped


def _batched(
    items: Iterable[PairT], size: int, stream_of: Callable[[PairT], object] | None
) -> Iterator[list[PairT]]:
    if stream_of is None:
        iterator = iter(items)
        while chunk := list(itertools.islice(iterator, size)):
            yield chunk
        return
    for _, stream in itertools.groupby(items, stream_of):
        yield from _batched(stream, size, None)


class SequentialRegistrar:
    """One pipeline for a whole stream; see the module docstring for its threading rule."""

    def __init__(self, settings: PipelineSettings) -> None:
        self._pipeline = RegistrationPipeline(settings)
        self._lock = threading.Lock()
        self._requested_settings: PipelineSettings | None = None
        self._requested_guess: InitialGuess | None = None
        self._reset_requested = threading.Event()

    @property
    def settings(self) -> PipelineSettings:
        """The settings in force for the pair being (or last) registered."""
        return self._pipeline.settings

    @property
    def previous(self) -> Similarity | None:
        """The warm start the next pair would start from (None: cold start)."""
        return self._pipeline.previous

    @property
    def pending_settings(self) -> PipelineSettings | None:
        """Settings requested but not yet applied (applied before the next pair)."""
        return self._requested_settings

    def request_settings(self, settings: PipelineSettings) -> None:
        """Any thread: use ``settings`` from the next pair on."""
        with self._lock:
            self._requested_settings = settings

    @property
    def pending_guess(self) -> InitialGuess | None:
        """An initial guess requested or set that no registration has used yet."""
        return self._requested_guess or self._pipeline.guess

    def request_guess(self, guess: InitialGuess) -> None:
        """Any thread: register the next pair around ``guess`` (cold, its sigmas bound the
        search); tracking goes on from that result."""
        with self._lock:
            self._requested_guess = guess

    def request_reset(self) -> None:
        """Any thread: forget warm start, cached model and frames before the next pair; the pair
        being registered now (if any) is dropped."""
        self._reset_requested.set()

    def __call__(self, pair: CloudPair) -> PairOutcome | None:
        self.apply_requests()
        outcome = self._pipeline.process(pair.model_cloud, pair.data_cloud)
        if self._reset_requested.is_set():
            return None  # reset while registering: the result belongs to the old state
        return outcome

    def apply_requests(self) -> None:
        """Owning thread only: apply what was requested (done before every pair anyway; an idle
        loop calls it so a reset takes effect at once)."""
        with self._lock:
            settings, self._requested_settings = self._requested_settings, None
            guess, self._requested_guess = self._requested_guess, None
        if settings is not None:
            self._pipeline.update_settings(settings)
        if self._reset_requested.is_set():
            self._reset_requested.clear()
            self._pipeline.reset()
        if guess is not None:
            self._pipeline.guess_next(guess)


@dataclass(frozen=True)
class ChunkRegistrar:
    """Consecutive pairs with one fresh pipeline: warm start within the chunk, picklable."""

    settings: PipelineSettings

    def __call__(self, chunk: Sequence[CloudPair]) -> list[PairOutcome]:
        pipeline = RegistrationPipeline(self.settings)
        return [pipeline.process(pair.model_cloud, pair.data_cloud) for pair in chunk]


@dataclass(frozen=True)
class IndependentRegistrar:
    """A fresh pipeline per pair: no warm start, no state, picklable."""

    settings: PipelineSettings

    def __post_init__(self) -> None:
        if self.settings.warm_start:
            raise ValueError("independent pairs cannot be warm-started; use a SequentialRegistrar")

    def __call__(self, pair: CloudPair) -> PairOutcome:
        return RegistrationPipeline(self.settings).process(pair.model_cloud, pair.data_cloud)
