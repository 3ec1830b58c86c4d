"""The sparse-to-dense levels of one registration and the pairs of one correspondence pass.

Sparse-to-dense (paper Eq. 4, 9): the sets are thinned into nested levels; the coarsest level is
solved from the initial guess, each finer level starts from the level above, the last level is
the full sets. With dense targets (``RegistrationConfig.dense_targets``) every level above the
screening one pairs a subset of each set with the *full* other set.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .config import RegistrationConfig
from .fit import Fit, measure_fit
from .kdtree import NearestNeighbors
from .overlap import Selection
from .points import centroid
from .poses import PoseBatch
from .prepared import PreparedModel
from .similarity import FloatArray, Similarity

# Points sampled to measure a set's spacing (median distance to the nearest other point).
_SPACING_SAMPLE = 256


@dataclass
class Level:
    """One resolution: the thinned sets, their trees, and what the loop needs to know of them."""

    data: FloatArray
    model: FloatArray
    data_tree: NearestNeighbors | None
    model_tree: NearestNeighbors
    data_mean: FloatArray
    model_mean: FloatArray
    data_second_moment: FloatArray
    data_spacing: float
    model_spacing: float

    @classmethod
    def build(
        cls,
        data: FloatArray,
        model: FloatArray,
        bidirectional: bool,
        backend: str,
        targets: tuple[NearestNeighbors | None, NearestNeighbors] | None = None,
    ) -> Level:
        if targets is None:
            data_tree = NearestNeighbors(data, backend) if bidirectional else None
            model_tree = NearestNeighbors(model, backend)
        else:
            data_tree, model_tree = targets
        return cls(
            data=data,
            model=model,
            data_tree=data_tree,
            model_tree=model_tree,
            data_mean=centroid(data),
            model_mean=centroid(model),
            data_second_moment=data.T @ data / data.shape[0],
            data_spacing=data_tree.spacing(_SPACING_SAMPLE) if data_tree else 0.0,
            model_spacing=model_tree.spacing(_SPACING_SAMPLE),
        )

    def motion(self, old: PoseBatch, new: PoseBatch) -> FloatArray:
        """RMS over the data of ||new(a) - old(a)||, per pose."""
        return old.motion(new, self.data_mean, self.data_second_moment)

    def fit(self, sim: Similarity) -> Fit:
        """The hits and near misses of ``sim`` on this level's trees (:func:`frisicp_core.fit.measure_fit`;
        bidirectional levels only: it needs the data's tree)."""
        assert self.data_tree is not None
        return measure_fit(sim, self.data_tree, self.model_tree, self.data_spacing, self.model_spacing)


@dataclass(frozen=True)
class Pairs:
    """One correspondence pass for K poses: each direction's pairs, their selection, the merit."""

    forward_index: np.ndarray  # (K, n_data): model point paired with each data point
    forward: Selection
    backward_index: np.ndarray | None  # (K, n_model): data point paired with each model point
    backward: Selection | None
    merit: FloatArray  # (K,): what the loop minimises, in distance units (see Solver.merit)

    def assign(self, rows: np.ndarray, other: Pairs) -> Pairs:
        """A copy with the pairs of poses ``rows`` (indices) replaced by ``other``'s."""
        forward_index = self.forward_index.copy()
        forward_index[rows] = other.forward_index
        backward_index, backward = self.backward_index, self.backward
        if backward_index is not None and backward is not None:
            assert other.backward_index is not None and other.backward is not None
            backward_index = backward_index.copy()
            backward_index[rows] = other.backward_index
            backward = backward.assign(rows, other.backward)
        merit = self.merit.copy()
        merit[rows] = other.merit
        return Pairs(forward_index, self.forward.assign(rows, other.forward), backward_index, backward, merit)

    def rms(self, k: int = 0) -> tuple[float, float, float]:
        """RMS of the kept pairs of pose k in the model frame: (both, forward, backward)."""
        forward = _rms(self.forward.sum_sq[k], self.forward.kept[k])
        if self.backward is None:
            return forward, forward, float("nan")
        both = _rms(
            self.forward.sum_sq[k] + self.backward.sum_sq[k], self.forward.kept[k] + self.backward.kept[k]
        )
        return both, forward, _rms(self.backward.sum_sq[k], self.backward.kept[k])


class Pyramid:
    """The levels of one registration, built when first used (a warm start may skip some)."""

    def __init__(
        self,
        pyramid: list[tuple[FloatArray, FloatArray]],
        data: FloatArray,
        model: PreparedModel,
        bidirectional: bool,
        config: RegistrationConfig,
    ) -> None:
        self._sets = pyramid
        self._full = (data, model)
        self._bidirectional = bidirectional
        self._config = config
        self._built: dict[int, Level] = {}
        self._targets: tuple[NearestNeighbors | None, NearestNeighbors] | None = None

    def __len__(self) -> int:
        """The number of levels (the last one holds the full sets)."""
        return len(self._sets)

    def screening_level(self) -> Level:
        """The coarsest sets thinned on both sides, with their own small trees: hypotheses far
        from the truth are screened where a query is cheapest. Without dense targets this is
        level 0 itself."""
        if not self._config.dense_targets:
            return self[0]
        if -1 not in self._built:
            self._built[-1] = Level.build(*self._sets[0], self._bidirectional, self._config.backend)
        return self._built[-1]

    def __getitem__(self, index: int) -> Level:
        if index not in self._built:
            backend = self._config.backend
            data, model = self._sets[index]
            targets = None
            if self._config.dense_targets or (data is self._full[0] and model is self._full[1].points):
                # The full model's tree is the prepared model's, built once for every registration
                # against it (frisicp_core.prepared); the data's, once per registration.
                if self._targets is None:
                    full_data = self._full[0]
                    data_tree = NearestNeighbors(full_data, backend) if self._bidirectional else None
                    self._targets = (data_tree, self._full[1].tree(backend))
                targets = self._targets
            self._built[index] = Level.build(data, model, self._bidirectional, backend, targets)
        return self._built[index]


def level_motion(config: RegistrationConfig, index: int, last: int) -> float:
    """Convergence tolerance of level ``index`` of ``last + 1``, relative to the model's radius.

    Geometric from ``coarse_relative_motion`` on the coarsest level to ``relative_motion`` on
    the full sets: each level hands the next a start that one or two of its (more expensive)
    iterations finish, instead of leaving the finest level to do the crawling.
    """
    criteria = config.criteria
    if last == 0:
        return criteria.relative_motion
    fraction = index / last
    return float(criteria.coarse_relative_motion ** (1.0 - fraction) * criteria.relative_motion**fraction)


def rows_of(pairs: Pairs, rows: np.ndarray) -> Pairs:
    """The pairs of poses ``rows`` only."""
    backward = pairs.backward
    return Pairs(
        pairs.forward_index[rows],
        pairs.forward.take(rows),
        pairs.backward_index[rows] if pairs.backward_index is not None else None,
        backward.take(rows) if backward is not None else None,
        pairs.merit[rows],
    )


def _rms(sum_sq: float, count: float) -> float:
    return float(np.sqrt(sum_sq / count)) if count > 0 else float("nan")
