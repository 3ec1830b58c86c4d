"""Finalists that come to an answer already reached are stopped there, not run to its end again.

The screening hands the first dense level a dozen finalists, and on real crops half of them lie
in one basin: each used to crawl 6-26 passes over the full sets to about the same pose, be
nominated as the answer's rival, and be run down every level into it again
(frisicp_core.solver.compare_finalists ``same_basin``, Solver.run_level ``joined``)."""

from __future__ import annotations

import time

import numpy as np

from frisicp_core import PreparedModel, RegistrationConfig, Similarity, axis_angle_rotation
from frisicp_core.ambiguity import separation
from frisicp_core.levels import Pyramid, level_motion
from frisicp_core.points import centroid, rms_radius
from frisicp_core.result import IterationRecord
from frisicp_core.sampling import downsample
from frisicp_core.solver import Solver, compare_finalists


def bumpy_shell(count: int, rng: np.random.Generator) -> np.ndarray:
    """Points on a lumpy, elongated closed surface: no symmetry, so one pose fits."""
    directions = rng.normal(size=(count, 3))
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    x, y, z = directions.T
    radius = 1.0 + 0.25 * np.sin(3 * x + 1) * np.cos(2 * y) + 0.15 * z**3
    return directions * radius[:, None] * np.array([2.0, 1.2, 0.8])


def turned(pose: Similarity, degrees: float, axis: tuple[float, float, float]) -> Similarity:
    """``pose`` followed by a turn of ``degrees`` about the model's origin."""
    return Similarity(1.0, axis_angle_rotation(np.array(axis), np.radians(degrees)), np.zeros(3)) @ pose


def compared(
    finalists: list[Similarity], same_answer: bool
) -> tuple[Similarity, list[Similarity], list[IterationRecord], list[int]]:
    """The finalists compared on the first dense level (500 data points against the 6,000 of the
    model) of a lumpy shell and a noisy 3,000-point sampling of it, whose truth is the identity:
    the winner, the runners-up, the winner's passes and every finalist's number of passes."""
    rng = np.random.default_rng(7)
    model_points = bumpy_shell(6000, rng)
    data = downsample(model_points, 3000, rng) + rng.normal(scale=0.005, size=(3000, 3))
    model = PreparedModel(model_points)
    config = RegistrationConfig()
    pyramid = Pyramid(
        [(downsample(data, 500, rng), model.points), (data, model.points)], data, model, True, config
    )
    solver = Solver(config, None, rms_radius(model.points), time.perf_counter())
    passes: list[int] = []
    run_level = solver.run_level

    def counted(*args, **kwargs):  # type: ignore[no-untyped-def]
        before = len(solver.history)
        outcome = run_level(*args, **kwargs)
        passes.append(len(solver.history) - before)
        return outcome

    solver.run_level = counted  # type: ignore[method-assign]
    centre, diagonal = centroid(data), model.diagonal

    def same_basin(a: Similarity, b: Similarity) -> bool:
        return separation(a, b, centre, diagonal, config.tolerance) <= 1.0

    (winner, _, _), runners_up = compare_finalists(
        solver,
        pyramid[0],
        finalists,
        relative_motion=level_motion(config, 0, 1),
        same_basin=same_basin if same_answer else None,
    )
    return winner, runners_up, solver.history, passes


TRUTH = Similarity(1.0, np.eye(3), np.zeros(3))
# Three starts in the truth's basin (4, 6 and 45 degrees off) and one in another (90 degrees).
FINALISTS = [
    turned(TRUTH, d, axis)
    for d, axis in ((4.0, (0, 0, 1)), (6.0, (1, 1, 0)), (45.0, (0, 1, 0)), (90.0, (0, 1, 0)))
]


def degrees_apart(a: Similarity, b: Similarity) -> float:
    return float(np.degrees(np.arccos(np.clip((np.trace(a.rotation @ b.rotation.T) - 1) / 2, -1, 1))))


def test_without_same_basin_every_start_in_the_answers_basin_crawls_to_it_and_stands_as_its_rival():
    winner, runners_up, _, passes = compared(FINALISTS, same_answer=False)
    assert degrees_apart(winner, TRUTH) < 0.1
    assert passes[1] >= 8 and passes[2] >= 14
    assert len(runners_up) == 2 and all(degrees_apart(r, winner) < 0.1 for r in runners_up)


def test_a_finalist_that_joins_an_earlier_answer_is_stopped_there_and_dropped():
    winner, runners_up, history, passes = compared(FINALISTS, same_answer=True)
    unstopped = compared(FINALISTS, same_answer=False)[3]
    assert degrees_apart(winner, TRUTH) < 0.1
    # The first start runs to its end; the next two stop on the pass that brings them within one
    # tolerance of that end, before they would have converged; the one in another basin runs
    # its own way.
    assert passes[0] == unstopped[0] and passes[3] == unstopped[3]
    assert passes[1] < unstopped[1] and passes[2] < unstopped[2]
    # Nothing is left to nominate as a rival of the answer, and the winner's passes are the
    # first start's own.
    assert runners_up == []
    assert len(history) == passes[0]


def test_a_start_given_twice_runs_once():
    # The descriptor search's rungs often refit to one pose; the copy would run the same passes
    # into the same end (without same_basin, to stand as the answer's rival).
    repeated = [FINALISTS[0], FINALISTS[3], FINALISTS[0], FINALISTS[3]]
    winner, runners_up, history, passes = compared(repeated, same_answer=False)
    once = compared(FINALISTS[::3], same_answer=False)
    assert passes == once[3] and len(passes) == 2
    assert np.array_equal(winner.matrix(), once[0].matrix())
    assert runners_up == [] and len(history) == passes[0]
