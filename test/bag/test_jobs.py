"""The process pool of `frisicp bag --jobs N` and signals: a Ctrl-C is never lost."""

from __future__ import annotations

import multiprocessing
import os
import signal
import threading
import time
from concurrent.futures.process import _ExecutorManagerThread

import numpy as np

from frisicp_ros.bag import jobs


def test_a_ctrl_c_while_workers_start_reaches_the_parent_however_the_kernel_delivers_it():
    """Starting workers set SIGINT to ignored for the whole process while blocking it in the main
    thread only: a Ctrl-C the kernel handed to another thread meanwhile was discarded (`frisicp
    bag --jobs 2` ran on to its end in 2 of 6 tries). Here it is sent while the main thread
    starts workers, from a thread that does not block it, where the kernel delivers it."""
    received: list[int] = []
    go, sent = threading.Event(), threading.Event()

    def other_thread() -> None:  # started before: SIGINT is not blocked in it
        go.wait(5)
        os.kill(os.getpid(), signal.SIGINT)
        sent.set()

    previous = signal.signal(signal.SIGINT, lambda signum, frame: received.append(signum))
    thread = threading.Thread(target=other_thread)
    thread.start()
    try:
        with jobs._starting_workers():
            go.set()
            assert sent.wait(5)
        deadline = time.monotonic() + 2
        while not received and time.monotonic() < deadline:
            time.sleep(0.01)  # the handler runs in the main thread, between bytecodes
        assert received == [signal.SIGINT]
    finally:
        thread.join()
        signal.signal(signal.SIGINT, previous)


def test_workers_ignore_a_ctrl_c_that_came_while_they_started():
    """The worker inherits the blocked mask: a signal pending since its start is discarded once
    its initializer ignores it, and it keeps working (the parent decides what stops)."""
    results = list(jobs.ordered_map(_signal_then_square, [2, 3, 4], jobs=2))
    assert results == [(2, 4), (3, 9), (4, 16)]


def _signal_then_square(value: int) -> int:
    os.kill(os.getpid(), signal.SIGINT)  # to itself: ignored
    return value * value


def test_stopping_early_leaves_no_thread_of_the_pool_for_the_exit_to_wait_for():
    """Closing the generator early kills the workers and returns only once the pool's manager
    thread has ended: interpreter exit joins that thread without a bound (`frisicp bag --jobs 2`
    once hung there after three Ctrl-C). Large inputs keep the call queue's feeder writing."""
    inputs = [np.full((40_000, 3), float(k)) for k in range(12)]
    mapped = jobs.ordered_map(_first_value, inputs, jobs=2)
    first_input, first_value = next(mapped)
    assert first_value == 0.0 and first_input is inputs[0]
    mapped.close()
    pool_threads = [t for t in threading.enumerate() if isinstance(t, _ExecutorManagerThread)]
    assert pool_threads == []
    assert multiprocessing.active_children() == []


def _first_value(points: np.ndarray) -> float:
    time.sleep(0.05)
    return float(points[0, 0])
