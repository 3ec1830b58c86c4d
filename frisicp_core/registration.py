"""FRISICP (Li et al., ICIP 2011) and the ICP baselines it is compared with, in one loop.

Objective (paper Eq. 3), for data A = {a_i} and model B = {b_j}:

    min_{s,R,t}  sum_i ||s R a_i + t - b_c(i)||^2  +  sum_j ||s R a_g(j) + t - b_j||^2

with c(i) the model point nearest to T(a_i) (Eq. 5, forward) and g(j) the data point whose image
is nearest to b_j (Eq. 6, backward). The backward term forbids the collapse s -> 0 that the
forward term alone allows. Each iteration fixes c and g and solves the union of both pair sets
in closed form (Eq. 7, :func:`estimate_similarities`). Eq. 8's incremental update composes to
the same absolute similarity, which is what is stored here.

Our defaults extend the paper where it assumes full overlap (each can be switched off, and
``RegistrationConfig.paper()`` switches all off):

- each direction keeps only the pairs of its estimated overlap (:mod:`frisicp_core.overlap`),
  and the merit of a pose is the sum of both directions' trimmed-ICP criterion psi;
- the scale is Horn's symmetric one and errors are measured half-way between the frames
  (merit^2 = (psi_f + psi_b) / s), so data onto model and model onto data are one problem;
- a cold start screens several initial hypotheses (:mod:`frisicp_core.hypotheses`), all
  iterated together as one batch on the coarsest level;
- Anderson acceleration (:mod:`frisicp_core.acceleration`).

Sparse-to-dense (Eq. 4, 9): the sets are thinned into nested levels; the coarsest level is
solved from the initial guess, each finer level starts from the level above, the last level is
the full sets. A level stops when the similarity stops moving (relative to the model's size) or
the merit stops falling; the result's errors are those of the last correspondence pass, so no
pass is spent re-measuring a similarity that moved by less than the tolerance.

Speed: a similarity scales all distances by s, so the data point nearest to b_j under T is the
data point nearest to T^-1(b_j). The backward search therefore queries a KD-tree built once per
level on the *untransformed* data with the model mapped by T^-1 (distances times s). Both trees
are built once per level, never per iteration.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import ArrayLike

from .acceleration import AndersonAccelerator
from .budget import Deadline
from .config import Method, RegistrationConfig
from .estimate import PairPart, estimate_similarities
from .hypotheses import covariance_scale_bounds, initial_hypotheses
from .kdtree import NearestNeighbors
from .overlap import Selection, select_pairs
from .points import as_point_set, centroid, check_same_dimension, rms_radius
from .poses import PoseBatch
from .result import IterationRecord, LevelReport, RegistrationResult
from .sampling import downsample, in_spatial_order, level_sizes
from .similarity import FloatArray, Similarity
from .units import Units
from .verdict import judge, spread

# Most passes a hypothesis gets on the screening level to settle into its local minimum.
_SCREENING_PASSES = 60
# Screening keeps the better half of each family of starting poses, ranked on every
# _ROUGH_EVERY-th point of its level, the best few after a few passes, then drops one whose merit
# is this many times the best one's (see _Solver.screen).
_ROUGH_EVERY = 4
_ROUGH_POINTS = 100
_SCREEN_PRUNE_FROM = 2
_KEEP_PER_FAMILY = 3
_SCREEN_PRUNE_RATIO = 2.0
# A hypothesis outside the finalists' margin whose merit, falling as fast as in its last pass,
# would not reach the margin within this many passes leaves: ICP's merit falls ever more slowly,
# and a sequence converging linearly at rate rho still has gain * rho / (1 - rho) to go, less than
# this many gains for rho < 10/11 (see _Solver.screen).
_SCREEN_HORIZON = 10.0
# Distinct minima whose screening merits are within this margin of the best are compared again on
# dense targets (at most this many): the thinned level can rank nearby basins wrongly.
_FINALIST_MARGIN = 0.25
_FINALISTS = 3
# A level's first step is significant when it moves the data by more than this many standard
# errors of the estimate (see ConvergenceCriteria.noise_floor): the usual three-sigma rule.
_SIGNIFICANT = 3.0
# First iteration of a level at which Anderson acceleration may propose steps. From a cold start
# the first steps are large and the pairs change under them: extrapolating from a single step
# misled it (bun045 -> bun000: 29 passes instead of 18). The refinement levels of a tracking
# start begin in the linear regime, where the remaining error is a slow slide along the
# surface, and waiting a step there costs one (10k-point node pairs of a moving sensor: mean
# 3.5 -> 3.0 passes).
_ACCELERATE_FROM = 3
_ACCELERATE_FROM_TRACKING = 2
# Points sampled to measure a set's spacing (median distance to the nearest other point).
_SPACING_SAMPLE = 256


@dataclass
class _Level:
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
    ) -> _Level:
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


@dataclass(frozen=True)
class _Pass:
    """One correspondence pass for K poses: each direction's pairs, their selection, the merit."""

    forward_index: np.ndarray  # (K, n_data): model point paired with each data point
    forward: Selection
    backward_index: np.ndarray | None  # (K, n_model): data point paired with each model point
    backward: Selection | None
    merit: FloatArray  # (K,): what the loop minimises, in distance units (see _Solver.merit)

    def assign(self, rows: np.ndarray, other: _Pass) -> _Pass:
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
        return _Pass(forward_index, self.forward.assign(rows, other.forward), backward_index, backward, merit)

    def rms(self, k: int = 0) -> tuple[float, float, float]:
        """RMS of the kept pairs of pose k in the model frame: (both, forward, backward)."""
        forward = _rms(self.forward.sum_sq[k], self.forward.kept[k])
        if self.backward is None:
            return forward, forward, float("nan")
        both = _rms(
            self.forward.sum_sq[k] + self.backward.sum_sq[k], self.forward.kept[k] + self.backward.kept[k]
        )
        return both, forward, _rms(self.backward.sum_sq[k], self.backward.kept[k])


class _Pyramid:
    """The levels of one registration, built when first used (a warm start may skip some)."""

    def __init__(
        self,
        pyramid: list[tuple[FloatArray, FloatArray]],
        data: FloatArray,
        model: FloatArray,
        bidirectional: bool,
        config: RegistrationConfig,
    ) -> None:
        self._sets = pyramid
        self._full = (data, model)
        self._bidirectional = bidirectional
        self._config = config
        self._built: dict[int, _Level] = {}
        self._targets: tuple[NearestNeighbors | None, NearestNeighbors] | None = None

    def screening_level(self) -> _Level:
        """The coarsest sets thinned on both sides, with their own small trees: hypotheses far
        from the truth are screened where a query is cheapest. Without dense targets this is
        level 0 itself."""
        if not self._config.dense_targets:
            return self[0]
        if -1 not in self._built:
            self._built[-1] = _Level.build(*self._sets[0], self._bidirectional, self._config.backend)
        return self._built[-1]

    def __getitem__(self, index: int) -> _Level:
        if index not in self._built:
            backend = self._config.backend
            targets = None
            if self._config.dense_targets:
                if self._targets is None:
                    full = _Level.build(*self._full, self._bidirectional, backend)
                    self._targets = (full.data_tree, full.model_tree)
                targets = self._targets
            self._built[index] = _Level.build(*self._sets[index], self._bidirectional, backend, targets)
        return self._built[index]


def _final_on_dense_targets(
    solver: _Solver, level: _Level, finalists: list[Similarity], relative_motion: float
) -> tuple[Similarity, LevelReport, _Pass]:
    """Run every finalist of the screening on the first dense level (the coarsest points against
    the full sets) and keep the one that ends with the lowest merit: with exact nearest
    neighbours the merits rank basins more reliably than on the thinned screening level."""
    outcomes = []
    for pose in finalists:
        history_before = len(solver.history)
        outcome = solver.run_level(0, level, pose, relative_motion=relative_motion)
        outcomes.append((float(outcome[2].merit[0]), outcome, solver.history[history_before:]))
        del solver.history[history_before:]
    _, best, history = min(outcomes, key=lambda item: item[0])
    solver.history.extend(history)
    return best


def _level_motion(config: RegistrationConfig, index: int, last: int) -> float:
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


def _finalists(minima: list[tuple[float, Similarity]], level: _Level, tolerance: float) -> list[Similarity]:
    """The distinct poses among ``minima`` within :data:`_FINALIST_MARGIN` of the best merit,
    best first, at most :data:`_FINALISTS`. Poses within three tolerances, or within one point
    spacing of the thinned level, are one minimum: hypotheses that settle into one basin stop a
    little apart on the thinned sets, and two finalists from one basin would crowd out another
    (a synthetic scan in its map: the right basin came fourth behind two copies of a wrong one)."""
    chosen: list[tuple[float, Similarity]] = []
    for value, pose in sorted(minima, key=lambda item: item[0]):
        if chosen and value > (1.0 + _FINALIST_MARGIN) * chosen[0][0]:
            break
        distances = [level.motion(PoseBatch.of([pose]), PoseBatch.of([other]))[0] for _, other in chosen]
        if all(d > max(_SIGNIFICANT * tolerance, level.model_spacing) for d in distances):
            chosen.append((value, pose))
        if len(chosen) == _FINALISTS:
            break
    return [pose for _, pose in chosen]


def _better_half(size: int) -> int:
    """How many of a family of ``size`` survive the rough ranking: half, at least _KEEP_PER_FAMILY."""
    return max(_KEEP_PER_FAMILY, (size + 1) // 2)


def _best_of_each(family: np.ndarray, merit: FloatArray, keep: int | Callable[[int], int]) -> np.ndarray:
    """Mask of the ``keep`` lowest merits within each family (``keep(family size)`` if callable)."""
    chosen = np.zeros(family.shape[0], dtype=bool)
    for member in np.unique(family):
        indices = np.flatnonzero(family == member)
        count = keep(indices.size) if callable(keep) else keep
        chosen[indices[np.argsort(merit[indices])[:count]]] = True
    return chosen


def _repeats_better(poses: PoseBatch, merit: FloatArray, level: _Level, tolerance: FloatArray) -> np.ndarray:
    """(K,) mask of the poses within their ``tolerance`` motion of another pose with a lower merit."""
    count = len(poses)
    repeats = np.zeros(count, dtype=bool)
    for k in range(count):
        others = poses.take(np.full(count, k))
        close = level.motion(others, poses) <= tolerance[k]
        repeats[k] = bool(np.any(close & (merit < merit[k])))
    return repeats


def _rms(sum_sq: float, count: float) -> float:
    return float(np.sqrt(sum_sq / count)) if count > 0 else float("nan")


class _Solver:
    """Runs one method's ICP iteration on a level, for one pose or a batch of hypotheses."""

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
        self.deadline = Deadline(config.budget_seconds, start)
        self.history: list[IterationRecord] = []

    def correspond(self, level: _Level, poses: PoseBatch) -> _Pass:
        """Pair every data point with its nearest model point and (FRISICP) vice versa."""
        count, dim = len(poses), level.data.shape[1]
        config = self.config
        forward_sq, forward_index = level.model_tree.query(poses.apply(level.data).reshape(-1, dim))
        forward_sq, forward_index = forward_sq.reshape(count, -1), forward_index.reshape(count, -1)
        forward = select_pairs(
            forward_sq, np.full(count, level.model_spacing**2), config.overlap, config.max_distance
        )
        backward_index: np.ndarray | None = None
        backward: Selection | None = None
        if self.bidirectional:
            assert level.data_tree is not None
            backward_sq, backward_index = level.data_tree.query(
                poses.apply_inverse(level.model).reshape(-1, dim)
            )
            # Measured in the data frame; times s gives the model frame, like the forward ones.
            backward_sq = backward_sq.reshape(count, -1) * poses.scale[:, None] ** 2
            backward_index = backward_index.reshape(count, -1)
            backward = select_pairs(
                backward_sq, (level.data_spacing * poses.scale) ** 2, config.overlap, config.max_distance
            )
        return _Pass(forward_index, forward, backward_index, backward, self.merit(forward, backward, poses))

    def merit(self, forward: Selection, backward: Selection | None, poses: PoseBatch) -> FloatArray:
        """sqrt of: psi_f + psi_b (estimated overlap), or the mean squared distance of the kept
        pairs of both directions together (fixed overlap; the paper's RMS); divided by s when
        errors are measured half-way between the frames (``symmetric``)."""
        if self.config.overlap is None:
            value = forward.merit + (backward.merit if backward is not None else 0.0)
        elif backward is None:
            value = forward.sum_sq / forward.kept
        else:
            value = (forward.sum_sq + backward.sum_sq) / (forward.kept + backward.kept)
        if self.config.symmetric:
            value = value / poses.scale
        merit: FloatArray = np.sqrt(value)
        return merit

    def step(self, level: _Level, pairs: _Pass) -> tuple[PoseBatch, np.ndarray]:
        """The closed-form similarity of each pose's kept pairs (Eq. 7) and which are valid."""
        parts = [
            PairPart(
                level.data,
                level.model_tree.points[pairs.forward_index],
                pairs.forward.keep.astype(np.float64),
            )
        ]
        if pairs.backward is not None and pairs.backward_index is not None:
            assert level.data_tree is not None
            parts.append(
                PairPart(
                    level.data_tree.points[pairs.backward_index],
                    level.model,
                    pairs.backward.keep.astype(np.float64),
                )
            )
        return estimate_similarities(
            parts,
            with_scale=self.with_scale,
            scale_bounds=self.scale_bounds,
            symmetric=self.config.symmetric,
            origin=(level.data_mean, level.model_mean),
        )

    def screen(self, level: _Level, families: list[list[Similarity]]) -> list[Similarity]:
        """Iterate the hypotheses together with plain (or accelerated) steps until each has
        settled into its local minimum; the distinct minima worth a closer look, best first.

        Partial overlap converges slowly and not geometrically, and a wrong basin often looks
        best early on (on smooth synthetic caps the right hypotheses overtake after 10-30
        passes), so hypotheses are compared once settled, not after a fixed number of passes.
        On the thinned screening level the merits of different basins can be within a few
        percent and in the wrong order, so every distinct minimum within
        :data:`_FINALIST_MARGIN` of the best is returned (at most :data:`_FINALISTS`), for the
        caller to compare on dense targets. To keep the batch small:

        - before the first pass, the better half of each family stays (at least
          :data:`_KEEP_PER_FAMILY`), ranked by the merits of the starting poses on a quarter of
          the level's points (:meth:`rough_merits`: the first pass over every start was most of
          a full-overlap cold start's screening); after :data:`_SCREEN_PRUNE_FROM` passes only
          the :data:`_KEEP_PER_FAMILY` best (members differ in one parameter, e.g. the scale of
          the data in place; their early merits rank them, but keeping three on the starting
          poses' merits alone dropped the right scale of a map onto its scan);
        - from then on, one whose merit is :data:`_SCREEN_PRUNE_RATIO` times the best's leaves
          (on 248 recorded screenings of the bunny cases the eventual winner was within 4 % of
          the best from the second pass on; on synthetic caps within 25 %);
        - from the pass after, one outside :data:`_FINALIST_MARGIN` of the best that falls too
          slowly to get inside it within :data:`_SCREEN_HORIZON` passes leaves (on a scan in its
          map, the principal-axes starts crawled at 1.7-2x the best merit for 30 passes and
          made up most of the screening's cost);
        - one within three standard errors of the pose of a better one, moving or settled,
          leaves (the same basin);
        - one that settles (its step moves the data by less than ``coarse_relative_motion``)
          leaves the batch and joins the settled minima.
        """
        hypotheses = [sim for family in families for sim in family]
        family = np.concatenate([np.full(len(f), k) for k, f in enumerate(families)])
        chosen = _best_of_each(family, self.rough_merits(level, hypotheses), _better_half)
        hypotheses = [sim for sim, keep in zip(hypotheses, chosen, strict=True) if keep]
        family = family[chosen]
        poses = PoseBatch.of(hypotheses)
        pairs = self.correspond(level, poses)
        tolerance = self.config.criteria.coarse_relative_motion * self.model_radius
        minima: list[tuple[float, Similarity]] = []  # settled hypotheses: (merit, pose)
        accelerators = (
            [AndersonAccelerator(sim, level.data_mean, self.model_radius) for sim in hypotheses]
            if self.config.acceleration
            else []
        )
        previous = np.full(len(poses), np.inf)  # each hypothesis's merit one pass earlier
        for iteration in range(1, _SCREENING_PASSES + 1):
            if self.deadline.passed():
                break  # the hypotheses as they stand (below)
            merit = np.where(np.isfinite(pairs.merit), pairs.merit, np.inf)
            stepped, valid = self.step(level, pairs)
            stepped = poses.where(valid, stepped)
            settled = (level.motion(poses, stepped) <= tolerance) | ~valid
            noise = _SIGNIFICANT * np.maximum(tolerance, self.standard_errors(pairs))
            minima += [(float(merit[k]), poses[int(k)]) for k in np.flatnonzero(settled & (merit < np.inf))]
            alive = ~settled & (merit < np.inf) & ~_repeats_better(stepped, merit, level, noise)
            for value, pose in minima:  # on its way to a settled minimum: the same basin, no better
                near = level.motion(PoseBatch.of([pose] * len(stepped)), stepped)
                alive &= (near > noise) | (merit < value)
            best = min([float(merit.min())] + [value for value, _ in minima])
            if iteration == _SCREEN_PRUNE_FROM:
                alive &= _best_of_each(family, merit, _KEEP_PER_FAMILY)
            if iteration >= _SCREEN_PRUNE_FROM:
                alive &= merit <= _SCREEN_PRUNE_RATIO * best
            if iteration > _SCREEN_PRUNE_FROM:  # too slow to become a finalist
                finalist = (1.0 + _FINALIST_MARGIN) * best
                alive &= (merit <= finalist) | (merit - finalist < _SCREEN_HORIZON * (previous - merit))
            if not alive.any():
                return _finalists(minima, level, tolerance)
            kept = np.flatnonzero(alive)
            family = family[alive]
            previous = merit[kept]
            accelerators = [accelerators[k] for k in kept] if accelerators else []
            poses, pairs = self._screening_step(
                level, poses.take(kept), stepped.take(kept), merit[kept], accelerators, iteration
            )
        merit = np.where(np.isfinite(pairs.merit), pairs.merit, np.inf)
        minima += [(float(merit[k]), poses[k]) for k in range(len(poses)) if merit[k] < np.inf]
        return _finalists(minima, level, tolerance)

    def rough_merits(self, level: _Level, hypotheses: list[Similarity]) -> FloatArray:
        """Merit of each starting pose on every :data:`_ROUGH_EVERY`-th point of ``level`` (fewer
        skipped on small sets, so each keeps at least :data:`_ROUGH_POINTS` points). The level is a
        random subset of each set, in storage order, so every k-th of its points is one too."""
        smaller = min(level.data.shape[0], level.model.shape[0])
        every = max(1, min(_ROUGH_EVERY, smaller // _ROUGH_POINTS))
        rough = _Level.build(
            level.data[::every], level.model[::every], self.bidirectional, self.config.backend
        )
        merit = self.correspond(rough, PoseBatch.of(hypotheses)).merit
        return np.where(np.isfinite(merit), merit, np.inf)

    def _screening_step(
        self,
        level: _Level,
        poses: PoseBatch,
        stepped: PoseBatch,
        merit: FloatArray,
        accelerators: list[AndersonAccelerator],
        iteration: int,
    ) -> tuple[PoseBatch, _Pass]:
        """Move every hypothesis on, by an Anderson proposal where one lowers its merit, else by
        its plain step; return the new poses and their pairs (as ``run_level`` does for one)."""
        proposals: dict[int, Similarity] = {}
        if accelerators and iteration >= _ACCELERATE_FROM:
            for k, accelerator in enumerate(accelerators):
                proposal = accelerator.propose(poses[k], stepped[k])
                if proposal is not None:
                    proposals[k] = proposal
        if not proposals:
            return stepped, self.correspond(level, stepped)
        rows = np.fromiter(proposals, dtype=np.int64)
        candidates = stepped.assign(rows, PoseBatch.of(list(proposals.values())))
        pairs = self.correspond(level, candidates)
        rejected = rows[~(pairs.merit[rows] < merit[rows])]
        if rejected.size == 0:
            return candidates, pairs
        for k in rejected:
            accelerators[k].reset()  # extrapolation overshot: take the plain step
        plain = stepped.take(rejected)
        return candidates.assign(rejected, plain), pairs.assign(rejected, self.correspond(level, plain))

    def run_level(
        self,
        index: int,
        level: _Level,
        sim: Similarity,
        *,
        relative_motion: float,
        accelerate_from: int = _ACCELERATE_FROM,
    ) -> tuple[Similarity, LevelReport, _Pass]:
        """Iterate correspond -> solve on one level until the similarity moves by less than
        ``relative_motion`` times the model's radius (or the merit stops falling).
        ``accelerate_from``: the first iteration that may take an Anderson step."""
        criteria = self.config.criteria
        tolerance = relative_motion * self.model_radius
        accelerator = (
            AndersonAccelerator(sim, level.data_mean, self.model_radius) if self.config.acceleration else None
        )
        pose = PoseBatch.of([sim])
        pairs = self.correspond(level, pose)
        merit = float(pairs.merit[0])
        converged = False
        iterations = 0
        for iterations in range(1, criteria.max_iterations + 1):
            if self.deadline.passed():
                iterations -= 1  # not run; not converged: the result will say "budget exceeded"
                break
            self._record(index, iterations, pairs)
            stepped, valid = self.step(level, pairs)
            if not valid[0]:
                break  # degenerate pairs (e.g. a collapsed scale): keep the last valid similarity
            # Below the noise: a level's first step within three standard errors of the estimate
            # says its start is already as good as this level can tell (a warm start, a finer
            # level after a converged coarser one); once it has moved, it iterates down to one.
            # The coarsest level decides the basin: it always runs down to its tolerance.
            significant = 0.0 if index == 0 else _SIGNIFICANT if iterations == 1 else 1.0
            if level.motion(pose, stepped)[0] <= max(tolerance, significant * self.standard_error(pairs)):
                # Converged. The step moved every point by less than the tolerance, so the errors
                # of the last pass are the returned similarity's: no pass to re-measure them.
                pose, converged = stepped, True
                break
            # Extrapolate only once a level crawls: on levels that converge in a couple of
            # steps, a rejected proposal would cost a wasted correspondence pass.
            proposal = (
                accelerator.propose(pose[0], stepped[0])
                if accelerator and iterations >= accelerate_from
                else None
            )
            if accelerator is not None and proposal is not None:
                proposed = PoseBatch.of([proposal])
                proposal_pairs = self.correspond(level, proposed)
                if proposal_pairs.merit[0] < merit:
                    pose, pairs, merit = proposed, proposal_pairs, float(proposal_pairs.merit[0])
                    continue
                accelerator.reset()  # extrapolation overshot: take the plain step
            previous = merit
            pose = stepped
            pairs = self.correspond(level, pose)
            merit = float(pairs.merit[0])
            if previous - merit <= criteria.relative_rmse * previous:
                converged = True
                break
        report = LevelReport(level.data.shape[0], level.model.shape[0], iterations, converged, pairs.rms()[0])
        return pose[0], report, pairs

    def standard_error(self, pairs: _Pass) -> float:
        """Standard error of the estimate of pose 0 (see :meth:`standard_errors`)."""
        return float(self.standard_errors(pairs)[0])

    def standard_errors(self, pairs: _Pass) -> FloatArray:
        """Standard error of each pose's estimate from one pass, RMS of its kept pairs / sqrt(their
        number): the noise floor of the convergence test (0 unless ``criteria.noise_floor``)."""
        if not self.config.criteria.noise_floor:
            return np.zeros(pairs.merit.shape[0])
        kept, sum_sq = pairs.forward.kept, pairs.forward.sum_sq
        if pairs.backward is not None:
            kept, sum_sq = kept + pairs.backward.kept, sum_sq + pairs.backward.sum_sq
        with np.errstate(invalid="ignore", divide="ignore"):
            error: FloatArray = np.where(kept > 0, np.sqrt(sum_sq) / kept, 0.0)
        return error

    def _record(self, level: int, iteration: int, pairs: _Pass) -> None:
        both, forward, backward = pairs.rms()
        self.history.append(
            IterationRecord(level, iteration, both, forward, backward, time.perf_counter() - self.start)
        )


def register(
    data: ArrayLike, model: ArrayLike, config: RegistrationConfig | None = None
) -> RegistrationResult:
    """Find the similarity T with model ≈ T(data) = s R data + t.

    ``data`` (N, m) and ``model`` (M, m) are point sets in any dimension m >= 2; no
    correspondences are needed, and they may overlap only partly, in either direction.
    ``config`` defaults to ``RegistrationConfig()``; ``RegistrationConfig.paper()`` runs the
    published algorithm exactly. Raises ``ValueError`` on unusable input (see
    :func:`as_point_set`). The result carries a plausibility verdict (``reliable``, ``reason``).

    A warm start (``config.initial``) whose result fails the plausibility verdict is retried
    cold: a poisoned start must not turn later good pairs into wrong answers.
    """
    config = config or RegistrationConfig()
    # Validated first, so that the units (frisicp_core.units) are those of the points used.
    data_set = as_point_set(data, "data", drop_nonfinite=config.drop_nonfinite)
    model_set = as_point_set(model, "model", drop_nonfinite=config.drop_nonfinite)
    units = Units.of(data_set, model_set)
    data_set, model_set = units.scaled(data_set, model_set)
    config = units.config(config)
    # A pose far off (a warm start from clouds in other units) throws points past float64: their
    # distances are inf (or NaN: inf times a scale that squared to 0), the pose's merit is not
    # finite and it is dropped, or the result is unreliable. numpy's warnings on the way would
    # only be noise on a node's stderr.
    with np.errstate(over="ignore", invalid="ignore"):
        result = _register(data_set, model_set, config)
        left = None if config.budget_seconds is None else config.budget_seconds - result.seconds
        if config.initial is not None and not result.reliable and (left is None or left > 0):
            cold = _register(data_set, model_set, replace(config, initial=None, budget_seconds=left))
            result = replace(cold, seconds=result.seconds + cold.seconds)
    return units.restore(result)


def _register(data: ArrayLike, model: ArrayLike, config: RegistrationConfig) -> RegistrationResult:
    start = time.perf_counter()
    data_set = as_point_set(data, "data", drop_nonfinite=config.drop_nonfinite)
    model_set = as_point_set(model, "model", drop_nonfinite=config.drop_nonfinite)
    check_same_dimension(data_set, model_set)
    data_radius, model_radius = rms_radius(data_set), rms_radius(model_set)
    data_set, model_set = in_spatial_order(data_set, data_radius), in_spatial_order(model_set, model_radius)

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
    solver = _Solver(config, scale_bounds, model_radius, start)
    bidirectional = config.method is Method.FRISICP
    last = len(pyramid) - 1

    levels = _Pyramid(pyramid, data_set, model_set, bidirectional, config)
    families = initial_hypotheses(data_set, model_set, config, scale_bounds)
    finalists = [families[0][0]]
    if sum(len(family) for family in families) > 1:
        finalists = solver.screen(levels.screening_level(), families)
    reports: list[LevelReport] = []
    sim, first, accelerate_from = finalists[0], 0, _ACCELERATE_FROM
    if config.initial is not None and config.dense_targets and last > 0:
        # Tracking: no hypotheses to screen, so the thinned screening level is skipped; the warm
        # start converges on the first dense level (its coarsest points against the full sets:
        # exact neighbours, so no thinning bias for the finer levels to undo, and one cheap pass
        # when the start is already that close), then refines.
        sim, report, pairs = solver.run_level(
            0, levels[0], sim, relative_motion=_level_motion(config, 0, last)
        )
        reports, first, accelerate_from = [report], 1, _ACCELERATE_FROM_TRACKING
    elif len(finalists) > 1:
        sim, report, pairs = _final_on_dense_targets(
            solver, levels[0], finalists, _level_motion(config, 0, last)
        )
        reports, first = [report], 1
    for index in range(first, last + 1):
        sim, report, pairs = solver.run_level(
            index,
            levels[index],
            sim,
            relative_motion=_level_motion(config, index, last),
            accelerate_from=accelerate_from,
        )
        reports.append(report)

    rms, forward_rms, backward_rms = pairs.rms()
    overlap_forward = float(pairs.forward.fraction[0])
    overlap_backward = float(pairs.backward.fraction[0]) if pairs.backward is not None else float("nan")
    kept = pairs.forward.kept[0] + (pairs.backward.kept[0] if pairs.backward is not None else 0.0)
    verdict = judge(
        sim,
        converged=reports[-1].converged,
        rms=rms,
        overlap_forward=overlap_forward,
        overlap_backward=overlap_backward,
        moment_scale=model_radius / data_radius,
        model_radius=model_radius,
        spreads=(spread(data_set), spread(model_set)),
    )
    budget = solver.deadline.reason
    return RegistrationResult(
        similarity=sim,
        rms=rms,
        forward_rms=forward_rms,
        backward_rms=backward_rms,
        fitness=float(kept) / (data_set.shape[0] + (model_set.shape[0] if bidirectional else 0)),
        converged=reports[-1].converged,
        levels=tuple(reports),
        history=tuple(solver.history),
        seconds=time.perf_counter() - start,
        method=config.method,
        overlap_forward=overlap_forward,
        overlap_backward=overlap_backward,
        reliable=verdict.reliable and not budget,
        reason="; ".join(reason for reason in (budget, verdict.reason) if reason),
        warm_started=config.initial is not None,
    )
