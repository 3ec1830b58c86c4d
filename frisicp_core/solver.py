"""One method's ICP iteration on a level, for one pose or a batch of hypotheses: correspondences,
the closed-form step, the screening of initial hypotheses and the run of one level.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import replace

import numpy as np

from .acceleration import AndersonAccelerator
from .budget import Deadline
from .config import Method, RegistrationConfig
from .estimate import PairPart, estimate_similarities
from .levels import Level, Pairs, rows_of
from .overlap import Selection, select_pairs, select_within
from .poses import PoseBatch
from .result import IterationRecord, LevelReport
from .similarity import FloatArray, Similarity
from .verdict import CLEAR_NEAR_SHARE, MAX_NEAR_SHARE

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
ACCELERATE_FROM = 3
ACCELERATE_FROM_TRACKING = 2
# The backward queries look this many times the forward pairs' cut-off far (Solver._backward_bound).
_BACKWARD_REACH = 5.0


def _finalists(minima: list[tuple[float, Similarity]], level: Level, tolerance: float) -> list[Similarity]:
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


def _repeats_better(poses: PoseBatch, merit: FloatArray, level: Level, tolerance: FloatArray) -> np.ndarray:
    """(K,) mask of the poses within their ``tolerance`` motion of another pose with a lower merit."""
    count = len(poses)
    repeats = np.zeros(count, dtype=bool)
    for k in range(count):
        others = poses.take(np.full(count, k))
        close = level.motion(others, poses) <= tolerance[k]
        repeats[k] = bool(np.any(close & (merit < merit[k])))
    return repeats


class Solver:
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

    def correspond(self, level: Level, poses: PoseBatch) -> Pairs:
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
            mapped = poses.apply_inverse(level.model)
            floor_sq = (level.data_spacing * poses.scale) ** 2
            bound = self._backward_bound(forward, floor_sq, poses.scale)
            backward_sq, backward_index = level.data_tree.query(mapped.reshape(-1, dim), bound)
            # Measured in the data frame; times s gives the model frame, like the forward ones.
            backward_sq = backward_sq.reshape(count, -1) * poses.scale[:, None] ** 2
            backward_index = backward_index.reshape(count, -1)
            if bound is None:
                backward = select_pairs(backward_sq, floor_sq, config.overlap, config.max_distance)
            else:
                backward, exact = select_within(backward_sq, floor_sq, (bound * poses.scale) ** 2)
                undecided = np.flatnonzero(~exact)
                for k in undecided:  # the cut may lie beyond the bound: the pose's pairs in full
                    far = ~np.isfinite(backward_sq[k])
                    far_sq, backward_index[k, far] = level.data_tree.query(mapped[k, far])
                    backward_sq[k, far] = far_sq * poses.scale[k] ** 2
                if undecided.size:
                    full = select_pairs(backward_sq[undecided], floor_sq[undecided], None, None)
                    backward = backward.assign(undecided, full)
        return Pairs(forward_index, forward, backward_index, backward, self.merit(forward, backward, poses))

    def _backward_bound(self, forward: Selection, floor_sq: FloatArray, scale: FloatArray) -> float | None:
        """How far (data units) the backward queries need look, or None for everywhere.

        A crop's backward pairs are mostly model points far from it, the most expensive queries
        a KD-tree answers, and the automatic selection drops them all. Both directions pair the
        same overlap at the same noise, so their cut-offs are alike: the backward queries look
        :data:`_BACKWARD_REACH` times the forward cut-off far (at least twice the data's
        spacing), and :func:`frisicp_core.overlap.select_within` keeps exactly the pairs the
        full queries would. A pose whose backward cut-off may lie beyond (12 of 1,978 pose-passes
        of 20,000-point crops of a room in it) has its far points queried in full. Fixed overlap
        and gating need every distance: no bound."""
        if self.config.overlap is not None or self.config.max_distance is not None:
            return None
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):  # a scale of 1e-200
            reach_sq = np.maximum(_BACKWARD_REACH**2 * forward.cut, 4.0 * floor_sq) / scale**2
            bound = float(np.sqrt(np.max(reach_sq)))
        return bound if np.isfinite(bound) else None

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

    def step(self, level: Level, pairs: Pairs) -> tuple[PoseBatch, np.ndarray]:
        """The closed-form similarity of each pose's kept pairs (Eq. 7) and which are valid."""
        parts = [
            PairPart(
                level.data,
                np.take(level.model_tree.points, pairs.forward_index, axis=0),
                pairs.forward.keep.astype(np.float64),
            )
        ]
        if pairs.backward is not None and pairs.backward_index is not None:
            assert level.data_tree is not None
            parts.append(
                PairPart(
                    np.take(level.data_tree.points, pairs.backward_index, axis=0),
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

    def screen(self, level: Level, families: list[list[Similarity]]) -> list[Similarity]:
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

    def settle(
        self,
        level: Level,
        poses: PoseBatch,
        tolerance: float,
        passes: int,
        done: Callable[[Similarity], bool] | None = None,
    ) -> tuple[PoseBatch, FloatArray]:
        """ICP steps for every pose of the batch until its plain step moves the data by less than
        ``tolerance`` (at most ``passes``), or ``done`` says its pose needs no more; the poses
        reached and their merits. Steps are Anderson-accelerated as in :meth:`screen` (a
        proposal is taken only where it lowers the merit): probes displaced by a clearly wrong
        amount crawl back along shallow directions, 15 plain passes on the bunny, 11 so."""
        pairs = self.correspond(level, poses)
        merit = np.where(np.isfinite(pairs.merit), pairs.merit, np.inf)
        active = np.flatnonzero(np.isfinite(merit))
        pairs = rows_of(pairs, active)  # the pairs of the active poses, in their order
        accelerators = (
            [AndersonAccelerator(poses[k], level.data_mean, self.model_radius) for k in range(len(poses))]
            if self.config.acceleration
            else []
        )
        for iteration in range(1, passes + 1):
            if active.size == 0 or self.deadline.passed():
                break
            current = poses.take(active)
            stepped, valid = self.step(level, pairs)
            stepped = current.where(valid, stepped)
            moved = level.motion(current, stepped)
            reached, pairs = self._screening_step(
                level,
                current,
                stepped,
                merit[active],
                [accelerators[k] for k in active] if accelerators else [],
                iteration,
            )
            poses = poses.assign(active, reached)
            merit[active] = np.where(np.isfinite(pairs.merit), pairs.merit, np.inf)
            going = valid & (moved > tolerance)
            if done is not None:
                going &= [not done(poses[int(k)]) for k in active]
            keep = np.flatnonzero(going)
            pairs, active = rows_of(pairs, keep), active[keep]
        return poses, merit

    def rough_merits(self, level: Level, hypotheses: list[Similarity]) -> FloatArray:
        """Merit of each starting pose on every :data:`_ROUGH_EVERY`-th point of ``level`` (fewer
        skipped on small sets, so each keeps at least :data:`_ROUGH_POINTS` points). The level is a
        random subset of each set, in storage order, so every k-th of its points is one too."""
        smaller = min(level.data.shape[0], level.model.shape[0])
        every = max(1, min(_ROUGH_EVERY, smaller // _ROUGH_POINTS))
        rough = Level.build(
            level.data[::every], level.model[::every], self.bidirectional, self.config.backend
        )
        merit = self.correspond(rough, PoseBatch.of(hypotheses)).merit
        return np.where(np.isfinite(merit), merit, np.inf)

    def _screening_step(
        self,
        level: Level,
        poses: PoseBatch,
        stepped: PoseBatch,
        merit: FloatArray,
        accelerators: list[AndersonAccelerator],
        iteration: int,
    ) -> tuple[PoseBatch, Pairs]:
        """Move every hypothesis on, by an Anderson proposal where one lowers its merit, else by
        its plain step; return the new poses and their pairs (as ``run_level`` does for one)."""
        proposals: dict[int, Similarity] = {}
        if accelerators and iteration >= ACCELERATE_FROM:
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
        level: Level,
        sim: Similarity,
        *,
        relative_motion: float,
        accelerate_from: int = ACCELERATE_FROM,
        joined: Callable[[Similarity], bool] | None = None,
    ) -> tuple[Similarity, LevelReport, Pairs]:
        """Iterate correspond -> solve on one level until the similarity moves by less than
        ``relative_motion`` times the model's radius (or the merit stops falling).
        ``accelerate_from``: the first iteration that may take an Anderson step. ``joined``: a
        pose for which it says True lies in a basin already run to its end (the caller's to
        know), so the iterations stop there, the report not converged and the pairs those of the
        pose before (a pose run into another's basin is dropped, not compared)."""
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
            if joined is not None and joined(stepped[0]):
                pose = stepped
                break
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

    def standard_error(self, pairs: Pairs) -> float:
        """Standard error of the estimate of pose 0 (see :meth:`standard_errors`)."""
        return float(self.standard_errors(pairs)[0])

    def standard_errors(self, pairs: Pairs) -> FloatArray:
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

    def _record(self, level: int, iteration: int, pairs: Pairs) -> None:
        both, forward, backward = pairs.rms()
        self.history.append(
            IterationRecord(level, iteration, both, forward, backward, time.perf_counter() - self.start)
        )


def compare_finalists(
    solver: Solver,
    level: Level,
    finalists: list[Similarity],
    relative_motion: float,
    margin: float = 0.15,
    near_share: Callable[[Similarity], float] | None = None,
    finish: Callable[[Similarity], Similarity] | None = None,
    nominable: int | None = None,
    same_basin: Callable[[Similarity, Similarity], bool] | None = None,
) -> tuple[tuple[Similarity, LevelReport, Pairs], list[Similarity]]:
    """Run every finalist of the screening on the first dense level (the coarsest points against
    the full sets) and keep the one that ends with the lowest merit: with exact nearest
    neighbours the merits rank basins more reliably than on the thinned screening level.

    With ``near_share`` (a pose's share of near misses, :mod:`frisicp_core.fit`): when the
    lowest merit's pose does not fit clearly (:data:`~frisicp_core.verdict.CLEAR_NEAR_SHARE`),
    the lowest merit among the poses that do wins. The merit rewards explaining more of each
    cloud (TrICP's xi^-(1 + lambda)), fair between poses that keep alike shares, not between a
    10 % crop laid where it belongs (it covers a tenth of the scene: backward xi 0.1) and one
    swollen over half the scene at six times the residuals, which the merit prefers and the fit
    check (:data:`~frisicp_core.verdict.MAX_NEAR_SHARE`) refuses; nor between a 30 % crop of a
    furnished room laid where it belongs (1 % near misses) and one laid half over the room both
    ways, which keeps 33-44 % near misses, passes the check, and had the lower merit where the
    search missed such crops (the synthetic rooms of benchmarks/structured_scenes.py
    ``--kinds furnished``). Overruling the objective takes a clear fit: a pose that merely
    passes the check may be another misfit.

    With ``finish`` as well (the point-to-plane steps of :mod:`frisicp_core.refine` on this
    level's full trees): when no pose fits clearly, those that pass the check are finished and
    judged again. Point-to-point ICP crawls along a crop's surfaces and stops where a step moves
    the data little or the trimmed merit ticks up, short of its minimum: on a 10 % crop of the
    rs1 room a descriptor start 5 degrees off the truth stopped 4.4 degrees off, 29 % near
    misses (the truth: 13 %), and a wrong pose swollen over the room won; finished, it ends
    0.4 degrees off at 13 %.

    Also returns the others' poses there whose merits are within ``margin`` of the winner's,
    best first (runners-up: possible competitors), of the first ``nominable`` finalists only
    when given: the later ones may win but are no rivals of their own.

    With ``same_basin`` (whether two poses are one answer, e.g. within the tolerances of each
    other): a finalist that comes to the same answer as one run before it is stopped there and
    dropped. Its basin is already in the comparison; run on, it would crawl to about the same
    pose (on 20,000-point crops of the rs1 room, 5-10 of 11-17 finalists did, 6-26 passes
    each), and be nominated as a rival of the answer only to be run down the levels into it."""
    outcomes: list[tuple[float, tuple[Similarity, LevelReport, Pairs], list[IterationRecord], int]] = []

    def joined(pose: Similarity) -> bool:
        return same_basin is not None and any(same_basin(pose, ended[1][0]) for ended in outcomes)

    for index, pose in enumerate(finalists):
        if any(np.array_equal(pose.matrix(), earlier.matrix()) for earlier in finalists[:index]):
            # The same start runs the same way: into a basin already in the comparison (the
            # descriptor search's rungs often refit to one pose: 1-4 of 10-14 finalists on 20,000-
            # point crops of the rs1 room; one crawled 35 passes before it met its twin's end).
            continue
        history_before = len(solver.history)
        outcome = solver.run_level(0, level, pose, relative_motion=relative_motion, joined=joined)
        history = solver.history[history_before:]
        del solver.history[history_before:]
        if not joined(outcome[0]):
            outcomes.append((float(outcome[2].merit[0]), outcome, history, index))
    outcomes.sort(key=lambda item: item[0])
    if near_share is not None and not near_share(outcomes[0][1][0]) <= CLEAR_NEAR_SHARE:
        shares = [near_share(outcome[0]) for _, outcome, _, _ in outcomes]
        clear = next((k for k in range(1, len(outcomes)) if shares[k] <= CLEAR_NEAR_SHARE), None)
        if clear is None and finish is not None:
            finished = []
            for k in range(1, len(outcomes)):
                if shares[k] <= MAX_NEAR_SHARE and not solver.deadline.passed():
                    _, (pose, report, _), history, index = outcomes[k]
                    pose = finish(pose)
                    pairs = solver.correspond(level, PoseBatch.of([pose]))
                    report = replace(report, rms=pairs.rms()[0])
                    outcomes[k] = (float(pairs.merit[0]), (pose, report, pairs), history, index)
                    finished.append(k)
            clear = min(
                (k for k in finished if near_share(outcomes[k][1][0]) <= CLEAR_NEAR_SHARE),
                key=lambda k: outcomes[k][0],
                default=None,
            )
        if clear is not None:
            outcomes.insert(0, outcomes.pop(clear))
    chosen, best, history, _ = outcomes[0]
    solver.history.extend(history)
    limit = len(finalists) if nominable is None else nominable
    runners_up = sorted(outcomes[1:], key=lambda item: item[0])
    return best, [
        outcome[0]
        for merit, outcome, _, index in runners_up
        if abs(merit - chosen) <= margin * chosen and index < limit
    ]
