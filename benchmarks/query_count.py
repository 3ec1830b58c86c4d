"""How many points a registration queries in frisicp_core's KD-trees, in full-resolution passes.

Wall time on a shared machine is noisy; the number of query points is not. One pass is every
point of both clouds queried once (a bidirectional nearest-neighbour pass at full resolution),
so ``passes = queried points / (n_data + n_model)``. Used by benchmarks/tracking_warm_start.py.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any

from frisicp_core.kdtree import NearestNeighbors


@contextmanager
def counting_queries() -> Iterator[Callable[[], int]]:
    """Within the block, ``NearestNeighbors.query`` counts its query points; the yielded
    function reads the count and resets it."""
    original = NearestNeighbors.query
    count = [0]

    def counted(self: NearestNeighbors, queries: Any) -> Any:
        count[0] += len(queries)
        return original(self, queries)

    def read() -> int:
        value, count[0] = count[0], 0
        return value

    NearestNeighbors.query = counted  # type: ignore[method-assign]
    try:
        yield read
    finally:
        NearestNeighbors.query = original  # type: ignore[method-assign]
