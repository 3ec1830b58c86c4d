"""The core's own threading: one OpenMP and one BLAS thread per registration.

A registration is a long chain of small operations: KD-tree queries of a few hundred to a few
hundred thousand points (pykdtree, OpenMP), 3x3 to 7x7 linear algebra and products of thin
matrices (OpenBLAS). Spread over threads, each of them costs more in waking and joining the
threads than it gains, and on a machine whose cores are busy with other work the threads wait
for each other: on this package's 2-core machine with one other busy process, ``register`` on
the bunny took 398 ms with OpenMP's default threads against 115 ms pinned to one
(issue 19; ``benchmarks/default_threads.py`` measures the ratio). Users should not have to know
to set ``OMP_NUM_THREADS=1``, so :func:`register <frisicp_core.register>` runs inside
:func:`one_thread`. Parallelism belongs one level up: ``frisicp bag --jobs`` runs registrations
in separate processes.

The limit is set with threadpoolctl (which changes the libraries' thread counts through their
own APIs, ``omp_set_num_threads`` and ``openblas_set_num_threads``, and restores them on exit) on
a controller made once: making one looks up every loaded library (about 1.7 ms), entering its
limit costs about 13 microseconds. The libraries it knows are those loaded when it is made, on
the first registration; numpy, scipy and pykdtree are all loaded by ``import frisicp_core``.
OpenMP's thread count is per calling thread, so registrations in different threads (a worker
thread of the node) are limited alike.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from functools import cache

from threadpoolctl import ThreadpoolController


@cache
def _controller() -> ThreadpoolController:
    return ThreadpoolController()


@contextmanager
def one_thread() -> Iterator[None]:
    """Within the block, OpenMP and BLAS use one thread (the previous counts are restored)."""
    with _controller().limit(limits=1):
        yield
