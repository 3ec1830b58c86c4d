"""Ordered parallel map over worker processes with a bounded number of pairs in flight.

Results come out in input order whatever the number of workers, and at most ``window`` inputs
are submitted ahead of the oldest unfinished one, so memory stays bounded on long bags.
``jobs == 1`` runs in this process: no pickling, no start-up cost.
"""

from __future__ import annotations

import multiprocessing
import os
import signal
from collections import deque
from collections.abc import Callable, Generator, Iterable, Iterator
from concurrent.futures import Future, ProcessPoolExecutor
from contextlib import contextmanager
from typing import TypeVar

InputT = TypeVar("InputT")
ResultT = TypeVar("ResultT")

# Each worker is one registration at a time; pykdtree's OpenMP threads would only make the
# workers fight over the cores (measured in docs/bag.md). Values a user set are respected.
WORKER_ENVIRONMENT = {"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}


def ordered_map(
    function: Callable[[InputT], ResultT], inputs: Iterable[InputT], jobs: int, window: int | None = None
) -> Generator[tuple[InputT, ResultT], None, None]:
    """Yield ``(input, function(input))`` in input order, computed by ``jobs`` processes.

    ``function`` and the inputs must be picklable when ``jobs > 1``. Closing the generator
    early (an interrupt, a consumer error) cancels everything not yet started.
    """
    if jobs < 1:
        raise ValueError(f"jobs must be >= 1, got {jobs}")
    if jobs == 1:
        for item in inputs:
            yield item, function(item)
        return
    window = window or 2 * jobs
    pending: deque[tuple[InputT, Future[ResultT]]] = deque()
    with _worker_environment():
        # spawn, not fork: a forked child would inherit the parent's OpenMP thread pool
        # (already sized) and any threads the caller runs.
        executor = ProcessPoolExecutor(
            max_workers=jobs, mp_context=multiprocessing.get_context("spawn"), initializer=_ignore_interrupts
        )
        try:
            for item in inputs:
                pending.append((item, executor.submit(function, item)))
                while len(pending) >= window:
                    oldest, future = pending.popleft()
                    yield oldest, future.result()
            while pending:
                oldest, future = pending.popleft()
                yield oldest, future.result()
        finally:
            executor.shutdown(wait=True, cancel_futures=True)


def _ignore_interrupts() -> None:
    """Ctrl-C reaches the whole process group; only the parent decides what stops, and how."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)


@contextmanager
def _worker_environment() -> Iterator[None]:
    """Set the worker variables while the pool starts its processes (they copy os.environ)."""
    saved = {name: os.environ.get(name) for name in WORKER_ENVIRONMENT}
    for name, value in WORKER_ENVIRONMENT.items():
        os.environ.setdefault(name, value)
    try:
        yield
    finally:
        for name, old in saved.items():
            if old is None:
                os.environ.pop(name, None)
            else:
                os.environ[name] = old
