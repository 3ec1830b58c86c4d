"""FRISICP (Li et al., ICIP 2011) and the ICP baselines it is compared with, in one loop.

Objective (paper Eq. 3), for data A = {a_i} and model B = {b_j}:

    min_{s,R,t}  sum_i ||s R a_i + t - b_c(i)||^2  +  sum_j ||s R a_g(j) + t - b_j||^2

with c(i) the model point nearest to T(a_i) (Eq. 5, forward) and g(j) the data point whose image
is nearest to b_j (Eq. 6, backward). The backward term forbids the collapse s -> 0 that the
forward term alone allows. Each iteration fixes c and g and solves the union of both pair sets
in closed form (Eq. 7, :func:`estimate_similarity`). Eq. 8's incremental update composes to the
same absolute similarity, which is what is stored here.

Sparse-to-dense (Eq. 4, 9): the sets are thinned into nested levels; the coarsest level is
solved from the initial guess, each finer level starts from the level above, the last level is
the full sets.

Speed: a similarity scales all distances by s, so the data point nearest to b_j under T is the
data point nearest to T^-1(b_j). The backward search therefore queries a KD-tree built once per
level on the *untransformed* data with the model mapped by T^-1 (distances times s). Both trees
are built once per level, never per iteration.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import ArrayLike

from .acceleration import AndersonAccelerator
from .config import Initialization, Method, RegistrationConfig
from .estimate import estimate_similarity
from .kdtree import NearestNeighbors
from .moments import covariance_scale_bounds, moment_guesses
from .points import as_point_set, check_same_dimension, rms_radius
from .result import IterationRecord, LevelReport, RegistrationResult
from .sampling import downsample, level_sizes
from .similarity import FloatArray, Similarity
from .verdict import judge

# Iterations each initial hypothesis gets on the coarsest level before the best is chosen:
# enough for the wrong ones to settle into their (higher-error) local minima.
_SCREENING_ITERATIONS = 10
# First iteration of a level at which Anderson acceleration may propose steps.
_ACCELERATE_FROM = 3


@dataclass
class _Level:
    """One resolution: the thinned sets, their trees and moments used by the motion test."""

    data: FloatArray
    model: FloatArray
    data_tree: NearestNeighbors | None
    model_tree: NearestNeighbors
    data_mean: FloatArray
    data_second_moment: FloatArray

    @classmethod
    def build(cls, data: FloatArray, model: FloatArray, bidirectional: bool, backend: str) -> _Level:
        return cls(
            data=data,
            model=model,
            data_tree=NearestNeighbors(data, backend) if bidirectional else None,
            model_tree=NearestNeighbors(model, backend),
            data_mean=data.mean(axis=0),
            data_second_moment=data.T @ data / data.shape[0],
        )

    def motion(self, old: Similarity, new: Similarity) -> float:
        """RMS over the data of ||new(a) - old(a)||, from the data's first two moments.

        With D = s'R' - sR and d = t' - t: mean ||D a + d||^2 = tr(D M2 D^T) + 2 d.D mean + |d|^2.
        """
        lin = new.scale * new.rotation - old.scale * old.rotation
        shift = new.translation - old.translation
        value = np.einsum("ij,jk,ik->", lin, self.data_second_moment, lin)
        value += 2.0 * shift @ lin @ self.data_mean + shift @ shift
        return float(np.sqrt(max(value, 0.0)))


@dataclass
class _Pairs:
    source: FloatArray  # data points
    target: FloatArray  # their model counterparts
    forward_sq: FloatArray  # kept squared distances, model frame
    backward_sq: FloatArray
    total: int  # pairs before trimming/gating


def _keep(dist_sq: FloatArray, config: RegistrationConfig) -> np.ndarray | None:
    """Indices of the pairs that enter the estimate (None = all), per the robustness options."""
    n = dist_sq.shape[0]
    keep: np.ndarray | None = None
    if config.overlap < 1.0:
        count = max(1, int(np.ceil(config.overlap * n)))
        if count < n:
            keep = np.argpartition(dist_sq, count - 1)[:count]
    if config.max_distance is not None:
        candidates = dist_sq if keep is None else dist_sq[keep]
        limit = config.max_distance**2 * float(np.median(candidates))
        inside = candidates <= limit
        if not inside.all():
            base = np.arange(n) if keep is None else keep
            keep = base[inside]
    return keep


class _Solver:
    """Runs the ICP loop of one method on one level."""

    def __init__(
        self,
        config: RegistrationConfig,
        scale_bounds: tuple[float, float] | None,
        model_radius: float,
        start: float,
    ) -> None:
        self.config = config
        self.bidirectional = config.method is Method.FRISICP
        self.with_scale = config.method is not Method.ICP
        self.scale_bounds = scale_bounds
        self.model_radius = model_radius
        self.start = start
        self.history: list[IterationRecord] = []

    def correspond(self, level: _Level, sim: Similarity) -> _Pairs:
        moved = sim.apply(level.data)
        fwd_sq, fwd_idx = level.model_tree.query(moved)
        keep_f = _keep(fwd_sq, self.config)
        src_f = level.data if keep_f is None else level.data[keep_f]
        dst_f = level.model[fwd_idx] if keep_f is None else level.model[fwd_idx[keep_f]]
        fwd_kept = fwd_sq if keep_f is None else fwd_sq[keep_f]
        if not self.bidirectional:
            return _Pairs(src_f, dst_f, fwd_kept, np.empty(0), fwd_sq.shape[0])
        assert level.data_tree is not None
        back_sq, back_idx = level.data_tree.query(sim.inverse().apply(level.model))
        back_sq *= sim.scale**2  # distances measured in the data frame, reported in the model frame
        keep_b = _keep(back_sq, self.config)
        if keep_b is None:
            src_b, dst_b, back_kept = level.data[back_idx], level.model, back_sq
        else:
            src_b, dst_b, back_kept = level.data[back_idx[keep_b]], level.model[keep_b], back_sq[keep_b]
        return _Pairs(
            np.concatenate((src_f, src_b)),
            np.concatenate((dst_f, dst_b)),
            fwd_kept,
            back_kept,
            fwd_sq.shape[0] + back_sq.shape[0],
        )

    def run_level(
        self, index: int, level: _Level, sim: Similarity, *, final: bool, max_iterations: int | None = None
    ) -> tuple[Similarity, LevelReport, _Pairs]:
        """Iterate correspond -> solve on one level until the similarity stops moving."""
        criteria = self.config.criteria
        max_iterations = max_iterations or criteria.max_iterations
        tolerance = (
            criteria.relative_motion if final else criteria.coarse_relative_motion
        ) * self.model_radius
        accelerator = (
            AndersonAccelerator(sim, level.data_mean, self.model_radius) if self.config.acceleration else None
        )
        pairs = self.correspond(level, sim)
        rms = _rms(pairs.forward_sq, pairs.backward_sq)
        converged = False
        iterations = 0
        for iterations in range(1, max_iterations + 1):
            self._record(index, iterations, pairs, rms)
            try:
                step = estimate_similarity(
                    pairs.source, pairs.target, with_scale=self.with_scale, scale_bounds=self.scale_bounds
                )
            except ValueError:
                break  # degenerate pairs (e.g. a collapsed scale): keep the last valid similarity
            if level.motion(sim, step) <= tolerance:
                sim, converged = step, True
                if final:  # report the errors of the returned similarity itself
                    pairs = self.correspond(level, sim)
                    rms = _rms(pairs.forward_sq, pairs.backward_sq)
                break
            # Extrapolate only once a level crawls: on levels that converge in a couple of
            # steps, a rejected proposal would cost a wasted correspondence pass.
            proposal = (
                accelerator.propose(sim, step) if accelerator and iterations >= _ACCELERATE_FROM else None
            )
            if proposal is not None:
                proposal_pairs = self.correspond(level, proposal)
                proposal_rms = _rms(proposal_pairs.forward_sq, proposal_pairs.backward_sq)
                if proposal_rms < rms:
                    sim, pairs, rms = proposal, proposal_pairs, proposal_rms
                    continue
                accelerator.reset()  # type: ignore[union-attr]  # overshot: take the plain (monotone) step
            previous_rms = rms
            sim = step
            pairs = self.correspond(level, sim)
            rms = _rms(pairs.forward_sq, pairs.backward_sq)
            if previous_rms - rms <= criteria.relative_rmse * previous_rms:
                converged = True
                break
        report = LevelReport(level.data.shape[0], level.model.shape[0], iterations, converged, rms)
        return sim, report, pairs

    def _record(self, level: int, iteration: int, pairs: _Pairs, rms: float) -> None:
        self.history.append(
            IterationRecord(
                level,
                iteration,
                rms,
                _rms(pairs.forward_sq),
                _rms(pairs.backward_sq),
                time.perf_counter() - self.start,
            )
        )


def _rms(*squared: FloatArray) -> float:
    count = sum(s.shape[0] for s in squared)
    if count == 0:
        return float("nan")
    return float(np.sqrt(sum(float(s.sum()) for s in squared) / count))


def _initial_guesses(
    data: FloatArray, model: FloatArray, config: RegistrationConfig, scale_bounds: tuple[float, float] | None
) -> list[Similarity]:
    if config.initial is not None:
        if config.initial.dim != data.shape[1]:
            raise ValueError(
                f"initial similarity is {config.initial.dim}-D but the points are {data.shape[1]}-D"
            )
        guesses = [config.initial]
    elif config.initialization is Initialization.IDENTITY:
        guesses = [Similarity.identity(data.shape[1])]
    else:
        guesses = moment_guesses(
            data, model, principal_axes=config.initialization is Initialization.PRINCIPAL_AXES
        )
        if config.method is Method.ICP:
            guesses = [
                Similarity(1.0, g.rotation, model.mean(axis=0) - g.rotation @ data.mean(axis=0))
                for g in guesses
            ]
    if scale_bounds is not None:
        # Du's method must start inside its bounds: from outside, the first clipped step can raise
        # the error, which the loop would take for convergence after one iteration.
        guesses = [
            Similarity(float(np.clip(g.scale, *scale_bounds)), g.rotation, g.translation) for g in guesses
        ]
    return guesses


def register(
    data: ArrayLike, model: ArrayLike, config: RegistrationConfig | None = None
) -> RegistrationResult:
    """Find the similarity T with model ≈ T(data) = s R data + t.

    ``data`` (N, m) and ``model`` (M, m) are point sets in any dimension m >= 2; no
    correspondences are needed. ``config`` defaults to ``RegistrationConfig()``;
    ``RegistrationConfig.paper()`` runs the published algorithm exactly. Raises ``ValueError``
    on unusable input (see :func:`as_point_set`).

    A warm start (``config.initial``) whose result fails the plausibility verdict is retried
    cold: a poisoned start must not turn later good pairs into wrong answers.
    """
    config = config or RegistrationConfig()
    result = _register(data, model, config)
    if config.initial is not None and not result.reliable:
        cold = _register(data, model, replace(config, initial=None))
        return replace(cold, seconds=result.seconds + cold.seconds)
    return result


def _register(data: ArrayLike, model: ArrayLike, config: RegistrationConfig) -> RegistrationResult:
    start = time.perf_counter()
    data_set = as_point_set(data, "data", drop_nonfinite=config.drop_nonfinite)
    model_set = as_point_set(model, "model", drop_nonfinite=config.drop_nonfinite)
    check_same_dimension(data_set, model_set)

    rng = np.random.default_rng(config.seed)
    sizes = level_sizes(data_set.shape[0], model_set.shape[0], config.levels, config.coarsest_points)
    # Nested thinning, fine to coarse (Eq. 4: A^l = f(A^(l-1))).
    pyramid = [(data_set, model_set)]
    for size in reversed(sizes[:-1]):
        finer_data, finer_model = pyramid[0]
        pyramid.insert(0, (downsample(finer_data, size, rng), downsample(finer_model, size, rng)))

    scale_bounds = (
        covariance_scale_bounds(data_set, model_set) if config.method is Method.BOUNDED_ICP else None
    )
    solver = _Solver(config, scale_bounds, rms_radius(model_set), start)
    bidirectional = config.method is Method.FRISICP
    last = len(pyramid) - 1

    coarsest = _Level.build(*pyramid[0], bidirectional, config.backend)
    guesses = _initial_guesses(data_set, model_set, config, scale_bounds)
    if len(guesses) > 1:
        # Screen the hypotheses with a short plain run each on the coarsest level; only the best
        # one is iterated on. (A smaller screening subset was tried: on noisy data its errors no
        # longer told a pose from its 180-degree flip; see test_noisy_resampled_cold_starts.)
        screener = _Solver(replace(config, acceleration=False), scale_bounds, solver.model_radius, start)
        screened = [
            screener.run_level(0, coarsest, g, final=False, max_iterations=_SCREENING_ITERATIONS)
            for g in guesses
        ]
        guesses = [min(screened, key=lambda outcome: outcome[1].rms)[0]]
    sim, report, pairs = solver.run_level(0, coarsest, guesses[0], final=last == 0)
    reports = [report]
    for index in range(1, last + 1):
        level = _Level.build(*pyramid[index], bidirectional, config.backend)
        sim, report, pairs = solver.run_level(index, level, sim, final=index == last)
        reports.append(report)

    forward_total = pairs.total - (model_set.shape[0] if bidirectional else 0)
    overlap_forward = pairs.forward_sq.shape[0] / max(forward_total, 1)
    overlap_backward = (
        pairs.backward_sq.shape[0] / max(pairs.total - forward_total, 1) if bidirectional else 1.0
    )
    verdict = judge(
        sim,
        converged=reports[-1].converged,
        rms=_rms(pairs.forward_sq, pairs.backward_sq),
        overlap_forward=overlap_forward,
        overlap_backward=overlap_backward,
        moment_scale=rms_radius(model_set) / rms_radius(data_set),
        model_radius=solver.model_radius,
    )
    return RegistrationResult(
        similarity=sim,
        rms=_rms(pairs.forward_sq, pairs.backward_sq),
        forward_rms=_rms(pairs.forward_sq),
        backward_rms=_rms(pairs.backward_sq) if bidirectional else float("nan"),
        fitness=(pairs.forward_sq.shape[0] + pairs.backward_sq.shape[0]) / pairs.total,
        converged=reports[-1].converged,
        levels=tuple(reports),
        history=tuple(solver.history),
        seconds=time.perf_counter() - start,
        method=config.method,
        overlap_forward=overlap_forward,
        overlap_backward=overlap_backward,
        reliable=verdict.reliable,
        reason=verdict.reason,
        warm_started=config.initial is not None,
    )
