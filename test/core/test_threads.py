"""register decides its own threading (frisicp_core.threads): OpenMP (pykdtree) and BLAS run one
thread inside the call, whatever the caller's setting, which is restored afterwards."""

from __future__ import annotations

from typing import ClassVar

from threadpoolctl import threadpool_info, threadpool_limits

from frisicp_bench.neighbours import neighbours_class
from frisicp_core import NearestNeighbors, Similarity, bumpy_surface, register


def thread_counts() -> dict[str, int]:
    """Threads per loaded OpenMP and BLAS library, by file."""
    return {info["filepath"]: info["num_threads"] for info in threadpool_info()}


class WatchingNeighbors(NearestNeighbors):
    """The core's KD-tree, noting the libraries' thread counts at every query."""

    seen: ClassVar[list[dict[str, int]]] = []

    def query(self, queries, bound=None):
        WatchingNeighbors.seen.append(thread_counts())
        return super().query(queries, bound)


def test_register_runs_one_thread_per_library_and_restores_the_callers_count():
    model = bumpy_surface(600, seed=1)
    data = Similarity(0.8, [[0, -1, 0], [1, 0, 0], [0, 0, 1]], [0.1, 0.2, 0.3]).apply(model)
    WatchingNeighbors.seen.clear()
    with threadpool_limits(limits=2):
        before = thread_counts()
        with neighbours_class(WatchingNeighbors):
            result = register(data, model)
        after = thread_counts()
    assert result.reliable, result.reason
    assert {"openmp", "blas"} <= {info["user_api"] for info in threadpool_info()}
    assert set(before.values()) == {2}
    assert len(WatchingNeighbors.seen) > 10
    assert all(counts == dict.fromkeys(before, 1) for counts in WatchingNeighbors.seen)
    assert after == before
