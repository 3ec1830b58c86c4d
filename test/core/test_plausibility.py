"""The plausibility verdict: what any correct registration satisfies, checked on every result."""

import numpy as np
import pytest

from frisicp_core import Similarity, Tolerance, axis_angle_rotation, bumpy_surface, judge, register
from frisicp_core.ambiguity import Competitor
from frisicp_core.points import spread
from frisicp_core.uncertainty import Uncertainty

GOOD = dict(
    converged=True, rms=0.01, overlap_forward=0.9, overlap_backward=0.4, moment_scale=2.0, model_radius=1.0
)


def test_a_plausible_result_is_reliable_with_no_reason():
    verdict = judge(Similarity(2.5, np.eye(3), np.zeros(3)), **GOOD)
    assert verdict.reliable and verdict.reason == ""


@pytest.mark.parametrize(
    ("change", "reason"),
    [
        (dict(converged=False), "did not converge"),
        (dict(rms=float("nan")), "not finite"),
        (dict(rms=0.5), "RMS"),
        (dict(overlap_backward=0.02), "overlap"),
        (dict(spreads=(1e15, 1.0)), "not the points of one scene"),
    ],
)
def test_each_failed_check_is_named(change, reason):
    verdict = judge(Similarity(2.5, np.eye(3), np.zeros(3)), **{**GOOD, **change})
    assert not verdict.reliable and reason in verdict.reason


def test_a_misfit_or_a_rival_pose_leaves_the_answer_undetermined_a_wide_sigma_does_not():
    """``determined`` tells a pose the data locate (only its sigmas exceed the tolerances) from
    one they do not (a misfit, an ambiguity): the registration states the prior for the latter."""
    answer = Similarity(2.5, np.eye(3), np.zeros(3))
    rival = Competitor(Similarity(2.5, axis_angle_rotation([0, 0, 1], 0.5), np.zeros(3)), 1.01, 29.0)
    wide = Uncertainty(np.diag([1e-4] * 4 + [1.0] * 3), np.zeros(3))
    limits = dict(tolerance=Tolerance(), model_diagonal=4.0)
    assert judge(answer, **GOOD).determined
    uncertain = judge(answer, **GOOD, uncertainty=wide, **limits)
    assert (
        not uncertain.reliable
        and uncertain.determined
        and "not determined to the tolerance" in uncertain.reason
    )
    assert not judge(answer, **GOOD, competitor=rival, **limits).determined
    assert not judge(answer, **{**GOOD, "rms": 0.5}).determined


@pytest.mark.parametrize("scale", [1e-39, 1.5e40, 0.1, 30.0])
def test_an_absurd_scale_is_never_reliable(scale):
    verdict = judge(Similarity(scale, np.eye(3), np.zeros(3)), **GOOD)
    assert not verdict.reliable and "scale" in verdict.reason


def test_spread_tells_coordinates_from_garbage_numbers():
    surface = bumpy_surface(3000)
    with np.errstate(invalid="ignore"):  # some swapped bytes are NaN patterns
        wrong_byte_order = surface.astype("<f4").view(">f4").astype(np.float64)
    wrong_byte_order = wrong_byte_order[np.isfinite(wrong_byte_order).all(axis=1)]
    assert spread(surface) < 3
    assert spread(wrong_byte_order) > 1e6


def test_a_garbage_model_never_yields_a_reliable_result():
    """Valid data against random bytes read as floats: refused before the search (the spread
    test up front; it used to give an unreliable result after a long search)."""
    rng = np.random.default_rng(0)
    data = bumpy_surface(500)
    for _ in range(10):
        with np.errstate(invalid="ignore"):
            garbage = np.frombuffer(rng.bytes(500 * 12), "<f4").reshape(-1, 3).astype(np.float64)
        garbage = garbage[np.isfinite(garbage).all(axis=1)]
        with pytest.raises(ValueError, match="model: not the points of one scene"):
            register(data, garbage)


def test_a_rival_clearly_below_the_answers_merit_is_named_a_better_fit():
    """A competitor below the answer's merit by more than the ambiguity margin is a better pose the
    probes found and the search did not settle on (registration's probe rounds): the reason says
    it fits better, not as well."""
    answer = Similarity(2.5, np.eye(3), np.zeros(3))
    turned = Similarity(2.5, axis_angle_rotation([0, 0, 1], 0.05), np.zeros(3))
    better = judge(answer, **GOOD, competitor=Competitor(turned, 0.8, 3.0))
    equal = judge(answer, **GOOD, competitor=Competitor(turned, 0.98, 3.0))
    assert not better.reliable and "fits better (merit ratio 0.800" in better.reason
    assert not equal.reliable and "fits as well (merit ratio 0.980" in equal.reason
