"""Bounded work: nonsense numbers are refused before any search, and a registration past its
time budget stops and says so (issue 17: a wrong byte order held the node's worker for 6-17 s)."""

import numpy as np
import pytest

from frisicp_core import RegistrationConfig, Similarity, axis_angle_rotation, bumpy_surface, kdtree, register

SURFACE = bumpy_surface(3000, seed=2)
TRUTH = Similarity(1.3, axis_angle_rotation((0.3, 1.0, 0.2), 0.4), [0.1, 0.2, -0.3])
MODEL = TRUTH.apply(SURFACE)


def wrong_byte_order(points: np.ndarray) -> np.ndarray:
    """float32 coordinates read with the other byte order, as a lying ``is_bigendian`` gives."""
    with np.errstate(invalid="ignore"):
        swapped = points.astype("<f4").view(">f4").astype(np.float64)
    return swapped[np.isfinite(swapped).all(axis=1)]


def test_numbers_that_are_no_scene_are_refused_before_any_kd_tree_is_built(monkeypatch):
    def no_search(*args, **kwargs):
        raise AssertionError("a KD-tree was built for numbers that are not coordinates")

    monkeypatch.setattr(kdtree.NearestNeighbors, "__init__", no_search)
    garbage = wrong_byte_order(SURFACE)
    for data, model, side in ((garbage, MODEL, "data"), (SURFACE, garbage, "model")):
        with pytest.raises(ValueError, match=rf"^{side}: not the points of one scene: their RMS radius is"):
            register(data, model)


def test_a_cloud_whose_points_are_mostly_one_point_is_refused_with_the_likely_cause():
    zeros = SURFACE.copy()
    zeros[:2000] = 0.0  # missing returns written as zeros
    with pytest.raises(ValueError, match=r"over half of them are one point \(missing returns"):
        register(zeros, MODEL)


def test_past_its_budget_a_registration_stops_at_the_next_check_and_is_unreliable():
    result = register(SURFACE, MODEL, RegistrationConfig(budget_seconds=1e-9))
    assert not result.reliable and not result.converged
    assert result.reason.startswith("budget exceeded: stopped after ")
    assert "of the 1e-09 s budget (budget_seconds)" in result.reason
    assert sum(result.iterations) == 0 and result.history == ()  # no iteration ran


def test_a_budget_that_is_not_reached_changes_nothing():
    unbounded = register(SURFACE, MODEL)
    bounded = register(SURFACE, MODEL, RegistrationConfig(budget_seconds=600.0))
    assert RegistrationConfig().budget_seconds is None
    assert bounded.reliable and bounded.reason == ""
    np.testing.assert_array_equal(bounded.similarity.matrix(), unbounded.similarity.matrix())
    assert bounded.iterations == unbounded.iterations


def test_a_warm_start_past_the_budget_is_not_retried_cold_with_a_fresh_budget():
    config = RegistrationConfig(initial=TRUTH, budget_seconds=1e-9)
    result = register(SURFACE, MODEL, config)
    assert result.warm_started and result.reason.startswith("budget exceeded")


def test_invalid_budgets_are_refused():
    for value in (0.0, -1.0):
        with pytest.raises(ValueError, match="budget_seconds must be positive or None"):
            RegistrationConfig(budget_seconds=value)
