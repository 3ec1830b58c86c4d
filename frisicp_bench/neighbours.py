"""Watching or replacing the nearest-neighbour searches of ``frisicp_core.register``, for the
speed scripts in ``benchmarks/``.

``RegistrationConfig.backend`` chooses among the core's own KD-tree libraries; the core has no
hook for another class. :func:`neighbours_class` puts a subclass of the public
:class:`frisicp_core.NearestNeighbors` in its place, in every ``frisicp_core`` module that uses
it, for one ``with`` block. A subclass keeps the whole public contract (``points``, ``query``,
``query_k``, ``spacing``) whichever part of the core calls it, and the substitution follows the
class wherever the core imports it; stand-ins that replaced private pieces (a class without
``spacing``, the levels' build method) broke as the core changed.

:func:`counting_queries` counts query points, the deterministic part of a registration's cost:
wall time on a shared machine is noisy, the number of query points is not. One *pass* is every
point of both clouds queried once (a bidirectional nearest-neighbour pass at full resolution),
so ``passes = queried points / (n_data + n_model)``.
"""

from __future__ import annotations

import sys
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import ClassVar

import numpy as np

from frisicp_core import FloatArray, NearestNeighbors


@contextmanager
def neighbours_class(cls: type[NearestNeighbors]) -> Iterator[None]:
    """Within the block, the core builds its trees as ``cls`` (a NearestNeighbors subclass)."""
    users = {
        name: module
        for name, module in list(sys.modules.items())
        if name.split(".")[0] == "frisicp_core"
        and getattr(module, "NearestNeighbors", None) is NearestNeighbors
    }
    if set(users) <= {"frisicp_core", "frisicp_core.kdtree"}:
        raise RuntimeError("no frisicp_core module builds NearestNeighbors: nothing to replace")
    modules = list(users.values())
    for module in modules:
        module.NearestNeighbors = cls  # type: ignore[attr-defined]
    try:
        yield
    finally:
        for module in modules:
            module.NearestNeighbors = NearestNeighbors  # type: ignore[attr-defined]


class _CountingNeighbors(NearestNeighbors):
    """The core's NearestNeighbors, counting the points its ``query`` is asked about."""

    queried: ClassVar[int] = 0

    def query(self, queries: FloatArray, bound: float | None = None) -> tuple[FloatArray, np.ndarray]:
        _CountingNeighbors.queried += len(queries)
        return super().query(queries, bound)


@contextmanager
def counting_queries() -> Iterator[Callable[[], int]]:
    """Within the block, the core's 1-NN queries are counted; the yielded function returns the
    number of query points since the last call (or the block's start) and resets it."""

    def read() -> int:
        value, _CountingNeighbors.queried = _CountingNeighbors.queried, 0
        return value

    _CountingNeighbors.queried = 0
    with neighbours_class(_CountingNeighbors):
        yield read
