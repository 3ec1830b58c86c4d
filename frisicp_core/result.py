"""What a registration returns (modelled on Open3D's RegistrationResult)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .ambiguity import Competitor
from .config import Method
from .fit import Fit
from .similarity import FloatArray, Similarity
from .uncertainty import Uncertainty


@dataclass(frozen=True)
class IterationRecord:
    """One iteration: errors measured with the similarity in force at its start. On the level that
    point-to-plane steps solve (:mod:`frisicp_core.refine`), ``rms`` is the RMS point-to-plane
    residual of the kept pairs and the per-direction errors are NaN."""

    level: int
    iteration: int
    rms: float
    forward_rms: float
    backward_rms: float
    seconds: float  # since the start of ``register``


@dataclass(frozen=True)
class LevelReport:
    data_points: int
    model_points: int
    iterations: int
    converged: bool
    rms: float


@dataclass(frozen=True)
class RegistrationResult:
    """The similarity mapping data into the model frame (model ≈ s R data + t) and its quality.

    Errors are root-mean-square nearest-point distances in the model frame over the pairs that
    were used (after trimming/gating): ``forward_rms`` data -> model, ``backward_rms``
    model -> data, ``rms`` over both pair sets together (the FRISICP objective, Eq. 3).
    ``fitness`` is the fraction of pairs used. ``history`` has one record per iteration.

    ``overlap_forward`` is the estimated share of the data points that lie on the model,
    ``overlap_backward`` the share of the model points that lie on the data (a scan in a map:
    about 1 and the scan's share of the map). ``reliable`` is the plausibility verdict
    (:mod:`frisicp_core.verdict`): False means do not trust or reuse this similarity, and
    ``reason`` says why. ``warm_started`` is True when the result comes from ``config.initial``
    (False after a cold start, including a fallback from an implausible warm start).
    ``uncertainty`` is the estimate's covariance and its 1-sigma summary
    (:class:`frisicp_core.uncertainty.Uncertainty`: ``scale`` relative, ``rotation_deg``,
    ``translation`` in model units at the data centroid; ``pose_covariance`` for ROS).
    ``competitor`` is a distinct pose that fits about as well, when one was found (the result
    is then not reliable: ambiguous); ``fit`` the hits and near misses where the clouds meet
    (:mod:`frisicp_core.fit`); ``retried`` says why a warm start was retried cold ('' if not).
    ``window_points``: the number of model points in the window around the predicted pose that
    the data were registered against (:mod:`frisicp_core.window`), None when the whole model was
    used; the overlaps, the RMS and the verdict are then the window's.
    ``depth_averaged``: the voxel edges (data units, model units) over which both clouds were
    averaged before they were registered, their depths coming in a depth camera's coarse steps
    (:mod:`frisicp_core.terraces`); None when they were registered as given. The levels' point
    counts and the overlaps are then the averages'.
    """

    similarity: Similarity
    rms: float
    forward_rms: float
    backward_rms: float
    fitness: float
    converged: bool
    levels: tuple[LevelReport, ...]
    history: tuple[IterationRecord, ...]
    seconds: float
    method: Method
    overlap_forward: float
    overlap_backward: float
    reliable: bool
    reason: str
    warm_started: bool
    uncertainty: Uncertainty | None = None
    competitor: Competitor | None = None
    fit: Fit | None = None
    retried: str = ""
    window_points: int | None = None
    depth_averaged: tuple[float, float] | None = None

    @property
    def covariance(self) -> FloatArray:
        """The (p, p) covariance of the similarity over (log-scale, rotation vector, displacement
        of the data centroid's image), see :mod:`frisicp_core.uncertainty`; all NaN when none was
        estimated (a result that failed before the final pairs existed)."""
        if self.uncertainty is None:
            dim = self.similarity.dim
            size = 1 + dim * (dim - 1) // 2 + dim
            return np.full((size, size), np.nan)
        return self.uncertainty.covariance

    @property
    def iterations(self) -> tuple[int, ...]:
        """Iterations per level, coarse to fine."""
        return tuple(level.iterations for level in self.levels)
