"""``frisicp bag --scheduler ADDRESS``: the registrations on a Dask cluster (``distributed``).

The client (the ``frisicp bag`` process) reads and pairs every bag as a local run does and
writes every result itself, in bag order. The cluster only registers: each task is one chunk of
consecutive pairs of one bag, carried as locators (``frisicp_ros.bag.locate``: the bag's path on
the shared filesystem and where each cloud is in it); the worker reads the clouds and registers
them with the same chunk registrar a local ``--jobs N`` run uses.

- At most a window of chunks (twice the cluster's worker threads, at least 4) is submitted ahead
  of the oldest unwritten one: memory stays bounded and the cluster stays busy across bags.
- A worker lost mid-run costs nothing: the scheduler runs its tasks again elsewhere (a result it
  held but had not handed over is computed again). The client receives one result per task and
  writes it once, in order, so a rerun can neither double nor drop a line.
- A task that fails on a worker (the bag unreadable there, a task that killed
  ``distributed.scheduler.allowed-failures`` workers) gives :class:`Unregistered` pairs: that
  bag stops with the reason, the others go on.
- Stopping early (Ctrl-C, SIGTERM, an output error) cancels this run's tasks on the cluster; a
  task already running finishes there and its result is dropped. The cluster stays up.
"""

from __future__ import annotations

import contextlib
import functools
import logging
import socket
import time
import uuid
from collections import deque
from collections.abc import Callable, Generator, Iterable, Sequence
from concurrent.futures import CancelledError
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from distributed import Client, Future, get_worker
from distributed.scheduler import KilledWorker

from frisicp_ros.bag.executors import (
    BatchPair,
    ExecutorError,
    Interruptible,
    Plan,
    Unregistered,
    chunk_notice,
    chunk_registrar,
    per_bag_chunks,
)
from frisicp_ros.bag.locate import BagSource, PairLocator, locate, read_pairs
from frisicp_ros.bag.reader import BagError, describe
from frisicp_ros.stream.pipeline import PairOutcome
from frisicp_ros.stream.settings import PipelineSettings

CONNECT_TIMEOUT_SEC = 10.0
_WINDOW_PER_THREAD = 2
_MIN_WINDOW = 4
_THREADS_REFRESH_SEC = 5.0  # how often the window follows workers joining or leaving
_CLOSE_TIMEOUT_SEC = 5.0


class ClusterError(Exception):
    """The scheduler cannot be reached; the message says where and why."""


@dataclass(frozen=True)
class ChunkTask:
    """What a cluster task gets: where the chunk's pairs are, not the clouds themselves."""

    source: BagSource
    pairs: list[PairLocator]


@dataclass(frozen=True)
class RegisterFromBag:
    """The task function: read the chunk's pairs from the bag, register them (on a worker)."""

    registrar: Callable[[Sequence[Any]], list[PairOutcome]]

    def __call__(self, task: ChunkTask) -> list[PairOutcome] | list[Unregistered]:
        try:
            pairs = read_pairs(task.source, task.pairs)
        except BagError as err:
            return [Unregistered(f"on worker {_this_worker()}: {err}")] * len(task.pairs)
        return self.registrar(pairs)


def _this_worker() -> str:
    try:
        return str(get_worker().address)
    except ValueError:  # called outside a worker (a test)
        return socket.gethostname()


class DaskCluster:
    """An executor on the Dask cluster whose scheduler is at ``address`` (or a scheduler file)."""

    def __init__(self, address: str, timeout: float = CONNECT_TIMEOUT_SEC) -> None:
        self.address = address
        # The client's own log lines ("Couldn't gather 1 keys, rescheduling" when a worker dies,
        # tracebacks when the scheduler is gone) describe what the scheduler repairs or what the
        # run reports itself, in one line, per bag.
        for name in ["distributed", *logging.root.manager.loggerDict]:  # Dask's config sets some
            if name.split(".")[0] == "distributed":
                logging.getLogger(name).setLevel(logging.CRITICAL)
        target = {"scheduler_file": address} if Path(address).is_file() else {"address": address}
        try:
            self.client = Client(**target, timeout=timeout, set_as_default=False, name="frisicp-bag")
        except (OSError, TimeoutError, ValueError) as err:
            raise ClusterError(
                f"cannot connect to the Dask scheduler at {address}: {describe(err)}"
            ) from None
        self.run_id = uuid.uuid4().hex[:8]
        self.workers_at_start = len(self.client.nthreads())
        self._threads = (0, 0.0)  # (threads, when counted)

    def plan(self, settings: PipelineSettings, interruptible: Interruptible) -> Plan:
        threads = self._worker_threads()
        workers = self.workers_at_start
        notice = f"--scheduler {self.address}: {workers} worker{'s' * (workers != 1)}, {threads} threads"
        if not threads:
            notice += " (none yet: the tasks wait for workers to join)"
        if settings.warm_start:
            notice += "; " + chunk_notice("the cluster")
        mapper = functools.partial(self._map, interruptible=interruptible)
        return Plan(chunk_registrar(settings), per_bag_chunks(mapper), notice)

    def close(self) -> str | None:
        try:
            workers = len(self.client.nthreads())
        except OSError:  # the scheduler is gone (the run has said so)
            workers = None
        with contextlib.suppress(Exception):
            self.client.close(timeout=_CLOSE_TIMEOUT_SEC)
        if workers is not None and workers != self.workers_at_start:
            return f"the cluster had {self.workers_at_start} workers at the start, {workers} at the end"
        return None

    def _worker_threads(self) -> int:
        threads, counted = self._threads
        if time.monotonic() - counted > _THREADS_REFRESH_SEC:
            with contextlib.suppress(OSError):  # a scheduler gone shows in the results' wait
                threads = sum(self.client.nthreads().values())
            self._threads = (threads, time.monotonic())
        return threads

    def _map(
        self,
        registrar: Callable[[Sequence[Any]], list[PairOutcome]],
        chunks: Iterable[list[BatchPair]],
        interruptible: Interruptible,
    ) -> Generator[tuple[list[BatchPair], list[Any]], None, None]:
        """``(chunk, outcomes)`` in chunk order; closing it early cancels the tasks not yet read."""
        task = RegisterFromBag(registrar)
        pending: deque[tuple[list[BatchPair], Future[Any]]] = deque()
        try:
            for number, chunk in enumerate(chunks):
                source = chunk[0].source
                locators = [locate(item.pair, source) for item in chunk]
                future = self.client.submit(
                    task,
                    ChunkTask(source, locators),
                    key=f"frisicp-bag-{self.run_id}-{number}",
                    priority=-number,  # oldest first: results are written in order
                    pure=False,
                )
                pending.append((chunk, future))
                while len(pending) >= max(_MIN_WINDOW, _WINDOW_PER_THREAD * self._worker_threads()):
                    yield self._result(*pending.popleft(), interruptible)
            while pending:
                yield self._result(*pending.popleft(), interruptible)
        finally:
            if pending:
                with contextlib.suppress(Exception):
                    self.client.cancel([future for _, future in pending])

    def _result(
        self, chunk: list[BatchPair], future: Future[Any], interruptible: Interruptible
    ) -> tuple[list[BatchPair], list[Any]]:
        try:
            with interruptible():
                outcomes = future.result()
        except KilledWorker as err:
            reason = f"its task was on workers that died, too often to try again ({err})"
            outcomes = [Unregistered(reason)] * len(chunk)
        except CancelledError:
            raise ExecutorError(
                f"the cluster at {self.address} cancelled this run's tasks (the scheduler restarted or is gone)"
            ) from None
        except Exception as err:  # noqa: BLE001 - whatever a task raised on a worker
            outcomes = [Unregistered(f"its task failed on the cluster: {describe(err)}")] * len(chunk)
        return chunk, outcomes
