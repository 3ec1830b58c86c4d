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

import functools
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import ArrayLike

from .ambiguity import (
    AMBIGUITY_MARGIN,
    Competitor,
    half_turns,
    merit_margin,
    merit_noise,
    merit_ratio,
    probe_starts,
    separation,
    symmetric_starts,
)
from .config import Initialization, Method, RegistrationConfig, Tolerance
from .fit import Fit
from .global_search import feature_starts
from .hypotheses import beyond_guess, covariance_scale_bounds, initial_hypotheses
from .levels import Level, Pairs, Pyramid, level_motion
from .near_probes import near_rival, near_starts
from .plane_arrangement import plane_starts
from .points import as_point_set, centroid, check_same_dimension, rms_radius, spread
from .poses import PoseBatch
from .prepared import PreparedModel
from .refine import Sets, difference, polish, uncertainty_of
from .result import IterationRecord, LevelReport, RegistrationResult
from .rotations import vector_size
from .sampling import downsample, in_spatial_order, level_sizes
from .similarity import FloatArray, Similarity
from .solver import ACCELERATE_FROM, ACCELERATE_FROM_TRACKING, Solver, compare_finalists
from .terraces import Averaged, average_terraces
from .threads import one_thread
from .uncertainty import Uncertainty
from .units import Units, magnitude_exponent
from .verdict import CLEAR_NEAR_SHARE, MAX_NEAR_SHARE, SCALE_RANGE, judge, uncertain_components
from .window import cut

# Most passes a probe of the answer (frisicp_core.ambiguity) takes to settle on the screening
# level, and the margin of the merit there within which it is run down the levels to be compared.
_PROBE_PASSES = 20
_NOMINATE = 0.15
# The same margin for the answer's twins (frisicp_core.ambiguity.symmetric_starts), measured where
# they start, each of which is run down when within it. Where they start, the exact twins in
# synthetic symmetric halls and shelf racks (independent samplings, 5,000 points) measured
# 0.98-1.25 times the answer's merit, their other half turns 1.38 and more; on real scenes the
# half turns of 5,000-point crops measured 3.1-6.3 (rs1) and 2.0-2.5 (the dragon), 1.00-1.05
# about the axis of cturtle's dome-shaped depth frame (itself never determined).
_NOMINATE_TWIN = 0.3
# Clouds whose estimated overlaps are both at least this cover each other (see _register).
_COMPLETE = 0.9
# The random stream of the global search with the clouds' roles swapped (see _register).
_SWAPPED_STREAM = 1
# The random stream of the answer's uncertainty (the split halves; see _register).
_UNCERTAINTY_STREAM = 2
# Most probes refined down the levels to be compared with the answer on the full sets.
_PROBE_REFINED = 3
# Rounds of probes around a better pose a probe found, before the search counts as unsettled: an
# arc of 60 % of the MPEG-7 apple's outline (benchmarks/partial_contours.py, s = 0.7) was
# probed to a better pose whose own probes found a pose better still, 3 degrees off the
# first: that one was dropped, and a pose 12 of its sigmas off the truth came out reliable.
_PROBE_ROUNDS = 3
# The factor (half an octave down) by which the search's comparison also shrinks the answer so
# far and its runners-up (see shrunk_starts).
_SHRINK = 2.0**-0.5


def register(
    data: ArrayLike,
    model: ArrayLike | PreparedModel,
    config: RegistrationConfig | None = None,
    *,
    previous: RegistrationResult | None = None,
) -> RegistrationResult:
    """Find the similarity T with model ≈ T(data) = s R data + t.

    ``data`` (N, m) and ``model`` (M, m) are point sets in any dimension m >= 2; no
    correspondences are needed, and they may overlap only partly, in either direction.
    ``model`` may also be a :class:`PreparedModel` (a map registered against many times: its
    trees, levels, normals and descriptors are kept between calls; the result is the same as
    with its array). ``config`` defaults to ``RegistrationConfig()``;
    ``RegistrationConfig.paper()`` runs the published algorithm exactly. Raises ``ValueError`` on
    unusable input (see :func:`as_point_set`). The result carries a verdict (``reliable``,
    ``reason``) and its uncertainty.

    Tracking: a warm start (``config.initial``, usually the last result's similarity) is
    retried cold when its result is not reliable, or, given the track's last result
    (``previous``), when it is clearly worse than the track (:func:`worse_than_track`: the pose
    jumped, relocalised, the map changed, and the warm start fell into a wrong minimum); of the
    two, the better one wins (:func:`better_of`). A poisoned start must not turn later good
    pairs into wrong answers.

    Big maps: with a warm start, or an initial guess whose scale is known, a model with many
    more points than the data is cut to a window around the predicted pose
    (:mod:`frisicp_core.window`) at full resolution, and the data are registered against that.
    A windowed result that fails as above is retried against the whole model (cold for a warm
    start, around the guess for a guess), and a reliable answer from there is refined in a
    window around itself, so that the two are compared, and the track goes on, alike.

    Depth cameras: two clouds that both come in a depth camera's coarse depth steps, each in its
    camera's frame, are registered as their averages over voxels a step wide
    (:mod:`frisicp_core.terraces`; ``config.average_depth_steps``), said by the result's
    ``depth_averaged``: frames from nearby viewpoints otherwise lock terrace onto terrace.

    OpenMP and BLAS run one thread inside the call (:mod:`frisicp_core.threads`).
    """
    config = config or RegistrationConfig()
    # Validated first, so that the units (frisicp_core.units) are those of the points used.
    data_set = as_point_set(data, "data", drop_nonfinite=config.drop_nonfinite)
    if isinstance(model, PreparedModel):
        units = Units.of_exponents(magnitude_exponent(data_set), model.exponent)
        data_set = units.scaled_data(data_set)
        prepared = model.in_units(units.model)
    else:
        model_set = as_point_set(model, "model", drop_nonfinite=config.drop_nonfinite)
        units = Units.of(data_set, model_set)
        data_set, model_set = units.scaled(data_set, model_set)
        prepared = PreparedModel.of(model_set)
    # Prepared either way, in the same units and order: the same steps and averages (and, for a
    # PreparedModel, its average kept for the next call).
    averaged = average_terraces(data_set, prepared) if config.average_depth_steps else None
    if averaged is not None:
        data_set, prepared = averaged.data, averaged.model
    # A pose far off (a warm start from clouds in other units) throws points past float64: their
    # distances are inf (or NaN: inf times a scale that squared to 0), the pose's merit is not
    # finite and it is dropped, or the result is unreliable. numpy's warnings on the way would
    # only be noise on a node's stderr.
    with np.errstate(over="ignore", invalid="ignore"), one_thread():
        result = _tracked(data_set, prepared, config, units, previous if config.initial is not None else None)
        if averaged is None:
            return result
        result = replace(
            result, depth_averaged=(averaged.edges[0] * units.data, averaged.edges[1] * units.model)
        )
        return _grid_checked(result, averaged, config, units)


def _grid_checked(
    result: RegistrationResult, averaged: Averaged, config: RegistrationConfig, units: Units
) -> RegistrationResult:
    """``result``, of clouds averaged over voxels (:mod:`frisicp_core.terraces`), with its
    uncertainty widened by what the voxel grid moves, and judged again.

    Where a voxel's walls fall is arbitrary, and a different grid gives different means: a bias
    both split halves share, so the covariance does not see it. Frame pairs at depth steps of
    1.75-2 % of the scene came out 1.02-1.05 % off in scale at a 3 sigma of 0.77-0.91 %
    (``benchmarks/depth_sensor.py --sensor-frames``, reports of 2026-12-06 before this check).
    So a reliable result is refined again from its own pose on the averages over grids moved by
    half a voxel (:meth:`Averaged.on_shifted_grids`, without probes), and the difference ``d``
    of the two answers is added to the covariance as ``d d^T``: taken as one standard deviation
    of the grid's effect, which one pair of grids cannot measure better. Where the widened 3
    sigma exceeds a tolerance the result is not reliable, and ``reason`` says so."""
    if not result.reliable or result.uncertainty is None:
        return result
    shifted = averaged.on_shifted_grids()
    again = _windowed(
        shifted.data,
        shifted.model,
        units.config(replace(config, initial=result.similarity, guess=None, probe=False)),
        units,
        None,
    )
    centre = centroid(averaged.data) * units.data  # the data's centroid in the given units
    step = difference(again.similarity, result.similarity, centre)
    covariance = result.uncertainty.covariance + np.outer(step, step)
    if not np.all(np.isfinite(covariance)):
        covariance = np.full_like(covariance, np.inf)
    uncertainty = replace(result.uncertainty, covariance=covariance)
    seconds = result.seconds + again.seconds
    problems = uncertain_components(uncertainty, config.tolerance, averaged.model.diagonal * units.model)
    if not problems:
        return replace(result, uncertainty=uncertainty, seconds=seconds)
    turn = np.degrees(np.linalg.norm(step[1 : 1 + vector_size(result.similarity.dim)]))
    apart = (
        f"averaged over a depth step's voxels, on grids half a voxel apart the answers differ by"
        f" {abs(step[0]):.2%} in scale and {turn:.2g} deg"
    )
    return replace(
        result,
        uncertainty=uncertainty,
        seconds=seconds,
        reliable=False,
        reason=f"{apart}: {'; '.join(problems)}",
    )


def _tracked(
    data: FloatArray,
    model: PreparedModel,
    config: RegistrationConfig,
    units: Units,
    track: RegistrationResult | None,
) -> RegistrationResult:
    """:func:`register` of clouds in safe units: a window when one applies, the retry."""
    scaled = units.config(config)
    result = _windowed(data, model, scaled, units, track)
    windowed = result.window_points is not None
    if config.initial is None and not (windowed and not result.reliable):
        return result
    why = "" if result.reliable else result.reason
    if not why and track is not None:
        why = worse_than_track(result, track)
    left = None if config.budget_seconds is None else config.budget_seconds - result.seconds
    if not why or (left is not None and left <= 0):
        return result
    # A warm start is retried cold; a guess around the guess again, on the whole model.
    other = units.restore(_register(data, model, replace(scaled, initial=None, budget_seconds=left)))
    if windowed and other.reliable:
        left = None if left is None else left - other.seconds
        if left is None or left > 0:
            again = replace(config, initial=other.similarity, guess=None, budget_seconds=left)
            refined = _windowed(data, model, units.config(again), units, None)
            if refined.reliable:
                other = replace(refined, seconds=other.seconds + refined.seconds, warm_started=False)
    best = better_of(result, other)
    retried = (
        "warm start retried cold"
        if config.initial is not None
        else "window around the guess retried on the whole model"
    )
    return replace(best, seconds=result.seconds + other.seconds, retried=f"{retried}: {why}")


def _windowed(
    data: FloatArray,
    model: PreparedModel,
    config: RegistrationConfig,
    units: Units,
    track: RegistrationResult | None,
) -> RegistrationResult:
    """One registration against the window of ``model`` that ``config`` predicts (or the whole
    model when none applies; :func:`frisicp_core.window.cut`), restored to the given units."""
    start = time.perf_counter()
    window = cut(data, model, config)
    cutting = time.perf_counter() - start
    result = units.restore(_register(data, window or model, config, track))
    if window is None:
        return result
    return replace(result, seconds=result.seconds + cutting, window_points=len(window))


# A warm result is worse than the track when its smaller overlap fell below this share of the
# track's, its RMS grew more than this factor, or its near-miss share rose by more than this.
_TRACK_OVERLAP = 0.8
_TRACK_RMS = 1.5
_TRACK_NEAR = 0.1


def worse_than_track(result: RegistrationResult, previous: RegistrationResult) -> str:
    """Why a warm-started ``result`` looks worse than the track's ``previous`` result, or ''.

    A tracked sensor sees much the same scene from one pair to the next: the overlap, the fit
    and the near misses change a little. A warm start left behind by a jump settles in some
    wrong minimum instead, where less of the clouds overlaps, the pairs fit worse and surfaces
    that meet miss each other.
    """
    if not previous.reliable:
        return ""
    problems = []
    now, before = _smaller_overlap(result), _smaller_overlap(previous)
    if now < _TRACK_OVERLAP * before:
        problems.append(f"overlap {now:.0%} where the track had {before:.0%}")
    if result.rms > _TRACK_RMS * previous.rms:
        problems.append(f"RMS {result.rms:.3g} where the track had {previous.rms:.3g}")
    if result.fit is not None and previous.fit is not None:
        near, was = result.fit.best_near_share, previous.fit.best_near_share
        if near > was + _TRACK_NEAR:
            problems.append(f"{near:.0%} near misses where the track had {was:.0%}")
    return "; ".join(problems)


def better_of(warm: RegistrationResult, cold: RegistrationResult) -> RegistrationResult:
    """The reliable one of two results for the same pair, else the one whose pairs fit better
    for their share (trimmed ICP's criterion: RMS^2 / fitness^3)."""
    if warm.reliable != cold.reliable:
        return warm if warm.reliable else cold
    return min((warm, cold), key=lambda result: result.rms**2 / max(result.fitness, 1e-12) ** 3)


def _smaller_overlap(result: RegistrationResult) -> float:
    values = [v for v in (result.overlap_forward, result.overlap_backward) if np.isfinite(v)]
    return min(values) if values else 0.0


def _register(
    data: FloatArray,
    model: PreparedModel,
    config: RegistrationConfig,
    track: RegistrationResult | None = None,
) -> RegistrationResult:
    """One registration of validated clouds in safe units (see :func:`register`)."""
    start = time.perf_counter()
    data_set, model_set = data, model.points
    check_same_dimension(data_set, model_set)
    data_radius, model_radius = rms_radius(data_set), model.radius
    data_set = in_spatial_order(data_set, data_radius)

    rng = np.random.default_rng(config.seed)
    sizes = level_sizes(data_set.shape[0], model_set.shape[0], config.levels, config.coarsest_points)
    # Nested thinning, fine to coarse (Eq. 4: A^l = f(A^(l-1))); the model's draws are the
    # prepared model's, remembered (the same subsets, the generator left where they leave it).
    pyramid = [(data_set, model_set)]
    model_level = model.levels()
    for size in reversed(sizes[:-1]):
        finer_data = pyramid[0][0]
        coarser_data = downsample(finer_data, size, rng)
        model_level = model.thinned(model_level, size, rng)
        pyramid.insert(0, (coarser_data, model_level.points))

    scale_bounds = (
        covariance_scale_bounds(data_set, model_set) if config.method is Method.BOUNDED_ICP else None
    )
    solver = Solver(config, scale_bounds, model_radius, start)
    bidirectional = config.method is Method.FRISICP
    last = len(pyramid) - 1

    levels = Pyramid(pyramid, data_set, model, bidirectional, config)
    families = initial_hypotheses(data_set, model_set, config, scale_bounds)
    finalists = [families[0][0]]
    if sum(len(family) for family in families) > 1:
        finalists = solver.screen(levels.screening_level(), families)
    reports: list[LevelReport] = []
    searching = (
        config.initial is None
        and config.guess is None
        and config.initialization is Initialization.SEARCH
        and config.method is Method.FRISICP
    )
    sim, first, accelerate_from = finalists[0], 0, ACCELERATE_FROM
    runners_up: list[Similarity] = []
    if config.initial is not None and config.dense_targets and last > 0:
        # Tracking: no hypotheses to screen, so the thinned screening level is skipped; the warm
        # start converges on the first dense level (its coarsest points against the full sets:
        # exact neighbours, so no thinning bias for the finer levels to undo, and one cheap pass
        # when the start is already that close), then refines.
        sim, report, pairs = solver.run_level(
            0, levels[0], sim, relative_motion=level_motion(config, 0, last)
        )
        reports, first, accelerate_from = [report], 1, ACCELERATE_FROM_TRACKING
    elif len(finalists) > 1 or (searching and last > 0):
        near_share = _NearShares(levels[0]) if bidirectional else None
        # Every comparison runs its poses on the first dense level, judged by the same fit check;
        # poses that pass it but not clearly are finished by the polish's steps when nothing
        # fits clearly (compare_finalists).
        finish = (
            _Finisher(levels[last], model, config, model_radius) if bidirectional and config.polish else None
        )
        on_first_level = functools.partial(
            compare_finalists,
            solver,
            levels[0],
            relative_motion=level_motion(config, 0, last),
            near_share=near_share,
            finish=finish,
            same_basin=_SameAnswer(centroid(data_set), model.diagonal, config.tolerance),
        )
        (sim, report, pairs), runners_up = on_first_level(finalists)
        reports, first = [report], 1
        if (
            searching
            and pairs.backward is not None
            and data_set.shape[1] == 3
            and (not _covering(pairs) or (near_share is not None and not near_share(sim) <= MAX_NEAR_SHARE))
            and not solver.deadline.passed()
        ):
            # The clouds do not cover each other: the data may lie anywhere in the model (or the
            # model in the data), at a scale and turn the moments do not tell. Or they cover each
            # other only at a pose that does not fit: a 30 % crop of the second dragon sampling,
            # swollen 47 % over its scene and 15 degrees off, seemed to cover it, and the search
            # was never asked. Poses from matched local shape (frisicp_core.global_search) join
            # the answer so far.
            # Each runs to its minimum on the first dense level: a start a few degrees off
            # the truth is still far above a settled wrong answer after a pass or two, so the
            # screening's early pruning would drop it. With them, the poses so far shrunk
            # (shrunk_starts): the merit favours a swollen pose. A shrunk start may win, but is
            # no rival to be run down the levels (_probe) when it does not: on an undetermined
            # 20 % crop one 93 degrees off, refined there, replaced an answer 1 degree off.
            starts = feature_starts(data_set, model, rng)
            # In a room of boxes the descriptors match nothing in particular; the arrangement of
            # its walls and floor does (frisicp_core.plane_arrangement; none elsewhere).
            planes = plane_starts(data_set, model)
            shrunk = shrunk_starts([sim, *runners_up], centroid(levels[0].data))
            unshrunk = [sim, *runners_up, *starts, *planes]
            (sim, report, pairs), runners_up = on_first_level([*unshrunk, *shrunk], nominable=len(unshrunk))
            reports = [report]
            if (
                near_share is not None
                and (not near_share(sim) <= CLEAR_NEAR_SHARE or (finish is not None and finish.made(sim)))
                and not solver.deadline.passed()
            ):
                # The search matches the data's local shapes onto the model's: it finds a crop
                # in its scene (each of the crop's keypoints has a counterpart there), hardly a
                # scene in its crop (most of the scene's have none). When its answer does not
                # fit, the same search the other way, the model's shapes onto the data's, has
                # its say; its poses, inverted, join. Its own generator leaves every later draw
                # as it was, so an answer that fits clearly is the one it always was. An answer
                # that fits only once finished (compare_finalists) is no sign the search found
                # its place: the whole dragon onto a 10 % crop of it ended shrunk 7x into the
                # crop, 95 degrees off; the swapped search finds the truth, which then fits
                # better. Nor is one that fits but not clearly (a third of its points near
                # misses): furnished rooms onto their 30 % crops lay the room shrunk into the
                # crop, covering 45-91 % of it where the truth covers 30 %, and pass the check;
                # asked then too, the swapped search set 6 of 12 right where 2 were (none lost,
                # and crops onto their rooms, where the first search finds its place, unchanged).
                # Asked whenever the search ran, it cost 35-80 % more on every partial overlap
                # and lost a right answer (the overlaps and this cost: one-off diagnostics of
                # 2026-12-07, docs/trust_history.md; the 6 of 12: structured_scenes.py).
                swapped = feature_starts(
                    model_set,
                    PreparedModel.of(data_set),
                    np.random.default_rng([config.seed, _SWAPPED_STREAM]),
                )
                if swapped:
                    inverted = [pose.inverse() for pose in swapped]
                    (sim, report, pairs), runners_up = on_first_level([sim, *runners_up, *inverted])
                    reports = [report]
    # The full sets are solved by point-to-plane steps (frisicp_core.refine) when polishing; ICP
    # runs the levels above them (all of them when the sets are small enough for one level).
    polishing = bidirectional and config.polish
    # Past the budget nothing more runs: the result is what the last pass had (and says so).
    icp_last = last - 1 if polishing and last > 0 else last
    for index in range(first, icp_last + 1):
        sim, report, pairs = solver.run_level(
            index,
            levels[index],
            sim,
            relative_motion=level_motion(config, index, last),
            accelerate_from=accelerate_from,
        )
        reports.append(report)

    competitors: list[Competitor] = []
    if bidirectional and config.initial is None and config.probe and not solver.deadline.passed():
        refine = _Refiner(solver, levels, config, icp_last)
        twins = (half_turns(data_set), half_turns(model_set))
        competitors, better = _probe(refine, sim, pairs, data_set, model_set, config, runners_up, twins)
        for _ in range(_PROBE_ROUNDS):
            if better is None:
                break
            sim, pairs, _ = better
            competitors, better = _probe(refine, sim, pairs, data_set, model_set, config, [], twins)
        if better is not None:
            # Each answer so far had a clearly better pose beside it: the search has not
            # settled, and this answer is no more the pose than the next would be. The better
            # pose is its competitor: the answer is not reliable.
            competitors = [better[2], *competitors]
    rms, forward_rms, backward_rms = pairs.rms()
    overlap_forward = float(pairs.forward.fraction[0])
    overlap_backward = float(pairs.backward.fraction[0]) if pairs.backward is not None else float("nan")
    kept = pairs.forward.kept[0] + (pairs.backward.kept[0] if pairs.backward is not None else 0.0)
    fitness = float(kept) / (
        pairs.forward.keep.shape[1] + (pairs.backward.keep.shape[1] if pairs.backward else 0)
    )
    final = levels[last]
    data_centroid = centroid(data_set)
    uncertainty: Uncertainty | None = None
    if polishing and solver.deadline.passed():
        polishing = False  # the finest level was not reached: say so (not converged)
        if last > 0:
            reports.append(LevelReport(final.data.shape[0], final.model.shape[0], 0, False, rms))
    if polishing:
        sets = _polish_sets(final, model, config)
        polished = polish(
            sim,
            sets,
            data_centroid,
            tolerance=level_motion(config, last, last) * model_radius,
            noise_floor=config.criteria.noise_floor,
        )
        sim, plane = polished.similarity, polished.pairs
        for iteration, plane_rms in enumerate(polished.history, start=1):
            solver.history.append(
                IterationRecord(
                    last, iteration, plane_rms, float("nan"), float("nan"), time.perf_counter() - start
                )
            )
        rms, forward_rms, backward_rms = plane.rms()
        overlap_forward, overlap_backward = plane.overlaps
        fitness = (plane.forward_sq.size + plane.backward_sq.size) / max(
            plane.forward_sampled + plane.backward_sampled, 1
        )
        report = LevelReport(
            final.data.shape[0], final.model.shape[0], len(polished.history), polished.converged, rms
        )
        if last == 0:  # one level: ICP and the steps shared it
            icp = reports.pop()
            report = replace(report, iterations=icp.iterations + report.iterations)
        reports.append(report)
        widening = track.uncertainty.widening if track is not None and track.uncertainty is not None else None
        # Its own stream: the split halves then depend on the clouds, the pose and the seed, not
        # on how many draws the search took to get there (a descriptor search takes many, a warm
        # start none), so one pose is given one uncertainty and one verdict however it was found.
        uncertainty = uncertainty_of(
            sim,
            plane,
            sets,
            data_centroid,
            np.random.default_rng([config.seed, _UNCERTAINTY_STREAM]),
            widening,
            limits=config.tolerance.limits(model.diagonal),
        )
        # A competitor found by ICP is judged against the polished answer, polished itself: two
        # ICP runs stopped at their noise floor may lie a tolerance apart in one basin.
        diagonal = model.diagonal
        competitors = [
            replace(other, similarity=finished, separation=apart)
            for other in competitors
            for finished in [polish(other.similarity, sets, data_centroid).similarity]
            for apart in [separation(finished, sim, data_centroid, diagonal, config.tolerance)]
            if apart > 1.0
        ]
    competitor = competitors[0] if competitors else None
    fit: Fit | None = None
    if bidirectional:
        fit = final.fit(sim)
    judged = functools.partial(
        judge,
        sim,
        converged=reports[-1].converged,
        rms=rms,
        overlap_forward=overlap_forward,
        overlap_backward=overlap_backward,
        moment_scale=model_radius / data_radius,
        model_radius=model_radius,
        spreads=(spread(data_set), model.spread),
        fit=fit,
        competitor=competitor,
        tolerance=config.tolerance,
        model_diagonal=model.diagonal,
    )
    verdict = judged(uncertainty=uncertainty)
    reliable, reason = verdict.reliable, verdict.reason
    if (
        reliable
        and polishing
        and uncertainty is not None
        and config.initial is None
        and config.probe
        and not solver.deadline.passed()
    ):
        # A reliable cold answer: is it pinned to the tolerance (frisicp_core.near_probes)?
        rival = near_rival(
            sim,
            rms,
            near_starts(sim, uncertainty, config.tolerance),
            sets,
            data_centroid,
            config.tolerance,
            model.diagonal,
            step_tolerance=level_motion(config, last, last) * model_radius,
            noise_floor=config.criteria.noise_floor,
        )
        if rival is not None:
            uncertainty = uncertainty.including(rival.offset)
            verdict = judged(uncertainty=uncertainty)
            reliable, reason = verdict.reliable, "; ".join(filter(None, (rival.describe(), verdict.reason)))
    budget = solver.deadline.reason
    if budget:
        reliable, reason = False, "; ".join(filter(None, (budget, reason)))
    if budget or not verdict.determined:
        # Judged on the local uncertainty (a misfit or an ambiguity is a reason of its own);
        # reported as the prior: near a pose that may be anywhere, the local one says nothing
        # about how far off it is (benchmarks/trustworthy.py: 57 / 44 / 28 % of such answers
        # within 3 local sigmas even with the competitor's offset added).
        plausible = model_radius / data_radius
        uncertainty = Uncertainty.undetermined(
            sim,
            sim.apply(data_centroid[None])[0],
            (plausible / SCALE_RANGE, plausible * SCALE_RANGE),
            model.bounds,
            float(np.sqrt(np.max(np.sum((data_set - data_centroid) ** 2, axis=1)))),
        )
    if config.guess is not None and config.initial is None:
        outside = beyond_guess(config.guess, sim, model_radius)
        if outside:
            reliable, reason = False, "; ".join(filter(None, (reason, outside)))
    return RegistrationResult(
        similarity=sim,
        rms=rms,
        forward_rms=forward_rms,
        backward_rms=backward_rms,
        fitness=fitness,
        converged=reports[-1].converged,
        levels=tuple(reports),
        history=tuple(solver.history),
        seconds=time.perf_counter() - start,
        method=config.method,
        overlap_forward=overlap_forward,
        overlap_backward=overlap_backward,
        reliable=reliable,
        reason=reason,
        warm_started=config.initial is not None,
        uncertainty=uncertainty,
        competitor=competitor,
        fit=fit,
    )


def shrunk_starts(poses: list[Similarity], data_centre: FloatArray) -> list[Similarity]:
    """``poses`` shrunk by :data:`_SHRINK` about where each puts ``data_centre`` (data frame).

    A trimmed bidirectional merit rewards a pose that explains more of each cloud, and a data
    cloud swollen over more of the model than it covers explains more of it: where the answer
    does not fit, or the clouds do not cover each other, the screening's minima may all lie on
    the swollen side. On a 2,000-point sparse map of the second dragon sampling (10 % outliers)
    every finalist was 20-40 % too large and 5-8 degrees off, and ICP on the first dense level
    did not shrink them back, while warm starts from the truth scaled by 0.71-0.84 and turned 30
    degrees return to it (test/core/test_sparse_maps.py). Shrunk by half an octave, such a
    finalist lands on the small side of the truth, from where ICP reaches it. (One turned the
    wrong way stays where it is: another sparse map's finalists, 11-15 degrees off, end there
    shrunk as well.)"""
    return [Similarity.about(pose.apply(data_centre), _SHRINK, np.eye(pose.dim)) @ pose for pose in poses]


class _NearShares:
    """A pose's share of near misses on ``level`` (:meth:`Level.fit`), measured once per pose
    object: the comparison of the finalists and the search's conditions ask about the same
    answer."""

    def __init__(self, level: Level) -> None:
        self.level = level
        self.measured: dict[int, tuple[Similarity, float]] = {}

    def __call__(self, pose: Similarity) -> float:
        known = self.measured.get(id(pose))
        if known is None or known[0] is not pose:  # the pose is kept, so its id is not reused
            known = (pose, self.level.fit(pose).best_near_share)
            self.measured[id(pose)] = known
        return known[1]


@dataclass(frozen=True)
class _SameAnswer:
    """Whether two poses are one answer: within one tolerance of each other
    (:func:`~frisicp_core.ambiguity.separation` about the data's ``centre``)."""

    centre: FloatArray
    diagonal: float
    tolerance: Tolerance

    def __call__(self, a: Similarity, b: Similarity) -> bool:
        return separation(a, b, self.centre, self.diagonal, self.tolerance) <= 1.0


def _second_look(refine: _Refiner, answer: Similarity, twin: Competitor) -> Competitor:
    """``twin`` (a rival from one of the answer's twins that came out worse than it, past the
    margin, on the finest level ICP ran) judged again on the full sets, where the most points
    tell the two apart: as a competitor there when it is within that margin there, else as it
    was. Its merit and the answer's come from two halves of the scene each laid over the other,
    and a thinned level's draw can favour one: in a hall with four tables (two independent
    samplings, 5,000 points each, a half turn apart) the answer 180 degrees off measured 15 %
    below the truth on 2,236 points (a margin of 12 %) and 2 % below it on all 5,000 (margin 8 %),
    where both converged within 2 % of each other."""
    finest = len(refine.levels) - 1
    if finest <= refine.last:
        return twin  # the finest level ICP ran holds the full sets: nothing more to see
    both = refine.solver.correspond(refine.levels[finest], PoseBatch.of([answer, twin.similarity]))
    selections = (both.forward, both.backward)
    ratio = merit_ratio(float(both.merit[1]), float(both.merit[0]))
    margin = merit_margin(merit_noise(selections), merit_noise(selections, row=1))
    if not (np.isfinite(ratio) and abs(ratio - 1.0) <= margin):
        return twin
    return Competitor(twin.similarity, ratio, twin.separation, margin)


@dataclass
class _Refiner:
    """Runs a pose down the levels from the first dense one, as the answer was."""

    solver: Solver
    levels: Pyramid
    config: RegistrationConfig
    last: int

    def settle_rough(
        self, starts: list[Similarity], returned: Callable[[Similarity], bool]
    ) -> tuple[PoseBatch, FloatArray]:
        """Every start settled on the thinned screening level (batched, accelerated ICP steps):
        cheap, and good enough to nominate candidates for :meth:`down`. A start that has
        ``returned`` (to the answer) is settled: its basin is the answer's."""
        tolerance = self.config.criteria.coarse_relative_motion * self.solver.model_radius
        level = self.levels.screening_level()
        return self.solver.settle(level, PoseBatch.of(starts), tolerance, _PROBE_PASSES, returned)

    def down(self, sim: Similarity, joined: Callable[[Similarity], bool]) -> tuple[Similarity, Pairs]:
        """``sim`` run down the levels as the answer was; its final pairs (the merit to compare).
        Stopped where ``joined`` says it came to the answer's basin: rivals nominated a
        tolerance or two off the answer crawl back to it on the full sets, 5-16 passes of them
        on 20,000-point crops of the rs1 room."""
        history = len(self.solver.history)
        for index in range(self.last + 1):
            sim, _, pairs = self.solver.run_level(
                index,
                self.levels[index],
                sim,
                relative_motion=level_motion(self.config, index, self.last),
                joined=joined,
            )
            if joined(sim):
                break
        del self.solver.history[history:]
        return sim, pairs


@dataclass
class _Finisher:
    """The polish's point-to-plane steps on the full sets (``final``, the last level), as a pose
    -> pose function: what :func:`compare_finalists` finishes crawling ICP poses with. Remembers
    the poses it returned (:meth:`made`)."""

    final: Level
    model: PreparedModel
    config: RegistrationConfig
    model_radius: float
    returned: list[Similarity] = field(default_factory=list)

    def __call__(self, pose: Similarity) -> Similarity:
        final, config = self.final, self.config
        sets = _polish_sets(final, self.model, config)
        tolerance = config.criteria.relative_motion * self.model_radius
        noise_floor = config.criteria.noise_floor
        finished = polish(
            pose, sets, centroid(final.data), tolerance=tolerance, noise_floor=noise_floor
        ).similarity
        self.returned.append(finished)
        return finished

    def made(self, pose: Similarity) -> bool:
        """Whether ``pose`` is one this finisher returned."""
        return any(pose is finished for finished in self.returned)


def _polish_sets(final: Level, model: PreparedModel, config: RegistrationConfig) -> Sets:
    """The full sets (``final``, the last level) as the polish sees them, with the model's normals."""
    assert final.data_tree is not None
    return Sets(
        final.data_tree,
        final.model_tree,
        final.data_spacing,
        final.model_spacing,
        model.normals(final.model_tree),
        overlap=config.overlap,
        max_distance=config.max_distance,
    )


def _covering(pairs: Pairs) -> bool:
    """True when each cloud's estimated overlap with the other is at least :data:`_COMPLETE`."""
    if pairs.backward is None:
        return bool(pairs.forward.fraction[0] >= _COMPLETE)
    return bool(min(pairs.forward.fraction[0], pairs.backward.fraction[0]) >= _COMPLETE)


def _probe(
    refine: _Refiner,
    sim: Similarity,
    pairs: Pairs,
    data: FloatArray,
    model: FloatArray,
    config: RegistrationConfig,
    runners_up: list[Similarity],
    twins: tuple[list[Similarity], list[Similarity]],
) -> tuple[list[Competitor], tuple[Similarity, Pairs, Competitor] | None]:
    """Probe the answer ``sim`` (final merit ``merit``; :mod:`frisicp_core.ambiguity`): starts
    around it settle on the screening level; those that end distinct from the answer settled
    there and within :data:`_NOMINATE` of its merit there are run down the levels like the
    answer and compared with it on the finest level ICP ran. Returns the competitors within the
    margin (best first), and a distinct pose that fits clearly better (with its final pairs,
    and as a competitor, its merit ratio below 1), if any: when the answer passes the fit
    check, a clearly lower merit that does not is no better, and when the answer fits clearly,
    one that does not fit clearly is no better
    (:func:`frisicp_core.solver.compare_finalists`: reached by swelling over more of a cloud).
    A competitor is judged by the merit alone, whether or not the rival fits (a wrong
    answer that passes the fit check had rivals that did not, on 5-10 % crops of the development
    scenes), unless the answer fits clearly (:data:`~frisicp_core.verdict.CLEAR_NEAR_SHARE`) and
    the rival does not: a crop swollen over its scene, 46-114 degrees off, matched the
    merit of right answers on 10-20 % crops once the descriptor search's agreement graph
    (:mod:`frisicp_core.compatibility`) put such poses among the runners-up, and a 30 % crop of
    a furnished room laid half over it both ways (33-44 % near misses) that of the crop laid
    where it belongs (1 %). The screening's ``runners_up`` are run down too, and so is every one
    of the answer's ``twins`` (the half turns of the data and of the model,
    :func:`~frisicp_core.ambiguity.symmetric_starts`)
    whose merit where it starts is within :data:`_NOMINATE_TWIN` of the answer's, and not
    beyond an initial guess (:func:`~frisicp_core.hypotheses.beyond_guess`); a twin that comes
    out worse past its margin is judged again on the full sets (:func:`_second_look`). (Clouds that cover each other
    are probed as well: two views of a dome-shaped depth frame overlap all but completely, and
    still turn a few degrees either way about the sensor at the same merit.)"""
    merit = float(pairs.merit[0])
    noise = merit_noise((pairs.forward, pairs.backward))
    level = refine.levels[refine.last]

    # The answer's near-miss share, fitted once for all of its tests below.
    answer_share = functools.cache(lambda: level.fit(sim).best_near_share)

    def fits(pose: Similarity) -> bool:
        """Whether a rival fits as well as a rival must: clearly where the answer fits clearly
        (a pose that lays a 30 % crop of a furnished room half over it both ways passes the fit
        check with a third of its points beside the surfaces, at the merit of the crop laid where
        it belongs), else it passes the check."""
        limit = CLEAR_NEAR_SHARE if answer_share() <= CLEAR_NEAR_SHARE else MAX_NEAR_SHARE
        return level.fit(pose).best_near_share <= limit

    centre = centroid(data)
    diagonal = float(np.linalg.norm(model.max(axis=0) - model.min(axis=0)))
    same_answer = _SameAnswer(centre, diagonal, config.tolerance)
    at_answer = functools.partial(same_answer, sim)
    starts = [sim, *probe_starts(sim, sim.apply(centre), sim.scale * rms_radius(data))]
    poses, merits = refine.settle_rough(starts, at_answer)
    settled = poses[0]

    def nominees(candidates: list[Similarity], merit_of: FloatArray, margin: float) -> list[Similarity]:
        """``candidates[1:]`` whose merit is within ``margin`` of ``candidates[0]``'s (the
        answer's) and that stand apart from the settled answer, lowest merit first."""
        ranked = sorted(
            (merit_ratio(float(merit_of[k]), float(merit_of[0])), k)
            for k in range(1, len(candidates))
            if np.isfinite(merit_of[k])
            and float(merit_of[k]) <= (1.0 + margin) * float(merit_of[0])
            and separation(candidates[k], settled, centre, diagonal, config.tolerance) > 1.0
        )
        return [candidates[k] for _, k in ranked]

    near = [*runners_up, *nominees([poses[k] for k in range(len(starts))], merits, _NOMINATE)]
    # The twins are measured where they start, not settled: the twin of a converged answer in a
    # symmetric scene is converged too, and the others would keep the batch running for all its
    # passes (the bunny's cold registrations took 1.5x as long). A twin meets other points: its
    # merit may lie past _NOMINATE by the thinned sets' sampling alone (merit_margin). An initial
    # guess says the answer is not beyond it: no twin there is a rival.
    guess = config.guess
    mirrored = [
        settled,
        *(
            twin
            for twin in symmetric_starts(settled, *twins)
            if guess is None or not beyond_guess(guess, twin, refine.solver.model_radius)
        ),
    ]
    screened = refine.solver.correspond(refine.levels.screening_level(), PoseBatch.of(mirrored))
    screen_noise = merit_noise((screened.forward, screened.backward))
    far = nominees(mirrored, screened.merit, max(_NOMINATE_TWIN, merit_margin(screen_noise, screen_noise)))
    found: list[Competitor] = []
    kept: list[Similarity] = []
    for start, is_twin in [*((pose, False) for pose in near), *((pose, True) for pose in far)]:
        if any(same_answer(start, other) for other in [sim, *kept]):
            continue  # the answer's basin, or one already run down
        if len(kept) >= _PROBE_REFINED and not is_twin:
            continue  # the near nominees' share is spent; every twin is run down
        kept.append(start)
        refined, rival = refine.down(start, at_answer)
        apart = separation(refined, sim, centre, diagonal, config.tolerance)
        ratio = merit_ratio(float(rival.merit[0]), merit)
        if apart <= 1.0 or not np.isfinite(ratio):
            continue
        # A twin met other points than the answer: their merits differ by the sampling too. A
        # near probe's rival keeps most of the answer's points, and 5 % tells them apart.
        margin = (
            merit_margin(noise, merit_noise((rival.forward, rival.backward))) if is_twin else AMBIGUITY_MARGIN
        )
        competitor = Competitor(refined, ratio, apart, margin)
        if is_twin and ratio > 1.0 + margin:
            competitor = _second_look(refine, sim, competitor)
        if competitor.better and (fits(refined) or not answer_share() <= MAX_NEAR_SHARE):
            return [], (refined, rival, competitor)
        # A rival that does not fit clearly matches the merit of an answer that does only by
        # swelling over more of a cloud (a crop over its scene) or by laying it half beside it:
        # no competitor.
        if abs(competitor.merit_ratio - 1.0) <= competitor.margin and (
            fits(refined) or not answer_share() <= CLEAR_NEAR_SHARE
        ):
            found.append(competitor)
    return sorted(found, key=lambda other: other.merit_ratio), None
