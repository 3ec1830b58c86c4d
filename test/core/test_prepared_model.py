"""A prepared model (frisicp_core.prepared) is the model array's registration, kept: the same
answers bit for bit, its tree, levels and normals built once; tracking against a big map cuts a
window around the predicted pose (frisicp_core.window) that answers as the whole map does, and a
wrong prediction is retried against the whole map."""

from __future__ import annotations

import numpy as np
import pytest

from frisicp_bench.terrain import Terrain, scan_errors
from frisicp_core import (
    InitialGuess,
    PreparedModel,
    RegistrationConfig,
    Similarity,
    axis_angle_rotation,
    bumpy_surface,
    register,
)
from frisicp_core import window as window_module

TRUTH = Similarity(1.3, axis_angle_rotation([0.3, 1.0, 0.2], 0.4), [0.1, -0.2, 0.3])
MODEL = bumpy_surface(3000, seed=3)
HALF = MODEL[MODEL[:, 0] < 0.2]


def same(first, second) -> bool:
    return (
        np.array_equal(first.similarity.matrix(), second.similarity.matrix())
        and first.rms == second.rms
        and first.reliable == second.reliable
        and first.reason == second.reason
        and first.levels == second.levels
        and np.array_equal(first.covariance, second.covariance, equal_nan=True)
    )


@pytest.mark.parametrize(
    ("data", "config"),
    [
        (TRUTH.inverse().apply(MODEL[::2]), RegistrationConfig()),
        (TRUTH.inverse().apply(HALF), RegistrationConfig()),
        (
            TRUTH.inverse().apply(MODEL[::2]),
            RegistrationConfig(initial=TRUTH @ Similarity(1.01, np.eye(3), [0.02, 0, 0])),
        ),
        (TRUTH.inverse().apply(MODEL[::2]), RegistrationConfig.paper(initialization="moments")),
        (TRUTH.inverse().apply(MODEL[::2]) * 2.0**90, RegistrationConfig()),  # other units
    ],
    ids=["cold", "part of the model", "warm", "paper", "units"],
)
def test_a_prepared_model_gives_the_arrays_result_every_time(data, config):
    """Once prepared, a model's trees, thinned levels and normals are reused, and the answers do
    not change: the thinned levels are the draws the array's registration makes."""
    by_array = register(data, MODEL, config)
    prepared = PreparedModel(MODEL)
    first = register(data, prepared, config)
    again = register(data, prepared, config)
    assert same(by_array, first) and same(by_array, again)
    assert by_array.reliable, by_array.reason


def test_a_prepared_model_keeps_what_it_built():
    prepared = PreparedModel(MODEL)
    register(TRUTH.inverse().apply(MODEL[::2]), prepared)
    tree = prepared.tree()
    register(TRUTH.inverse().apply(MODEL[1::2]), prepared)
    assert prepared.tree() is tree
    assert prepared.normals(tree) is prepared.normals(tree)


def test_a_prepared_model_owns_its_points():
    points = MODEL.copy()
    prepared = PreparedModel(points)
    points[:] = 0.0  # the caller's array changes: the prepared model does not
    assert not np.array_equal(prepared.points, points)
    assert not prepared.points.flags.writeable
    with pytest.raises(ValueError, match="model: 2 points is too few"):
        PreparedModel(MODEL[:2])


# --- tracking against a big map -----------------------------------------------------------------

TERRAIN = Terrain(0)
MAP = PreparedModel(TERRAIN.map_points(100_000))
POSE = TERRAIN.pose(3.0)


def scan(reach: float = 8.0, count: int = 5000, seed: int = 5) -> np.ndarray:
    return TERRAIN.scan(POSE, count, np.random.default_rng(seed), reach=reach)


def nudged(pose: Similarity, shift: float) -> Similarity:
    return Similarity(
        pose.scale * 1.003,
        axis_angle_rotation([0, 0, 1], np.deg2rad(0.5)) @ pose.rotation,
        pose.translation + shift,
    )


def test_tracking_registers_against_a_window_of_the_map_around_the_prediction():
    data = scan()
    result = register(data, MAP, RegistrationConfig(initial=nudged(POSE, 0.2)))
    assert result.reliable, result.reason
    assert result.window_points is not None and result.window_points < 0.1 * len(MAP)
    rotation, scale, shift = scan_errors(result.similarity, POSE, data)
    assert rotation < 0.1 and scale < 0.002 and shift < 0.001


def test_a_window_answers_as_the_whole_map_does(monkeypatch):
    """A scan covering an eighth of the map: right against the whole map and against the window
    (a random sampling of it at three times the scan's points), and the two answers agree within
    three of the windowed answer's standard deviations in every component."""
    data = scan(reach=20.0, count=8000)
    config = RegistrationConfig(initial=nudged(POSE, 0.3))
    windowed = register(data, MAP, config)
    monkeypatch.setattr(window_module, "MIN_MODEL", 10**12)  # no model is big enough for a window
    whole = register(data, MAP, config)
    assert windowed.window_points is not None and whole.window_points is None
    assert windowed.reliable and whole.reliable, (windowed.reason, whole.reason)
    sigma = windowed.uncertainty
    assert sigma is not None
    centre = data.mean(axis=0, keepdims=True)
    shift = np.linalg.norm(windowed.similarity.apply(centre) - whole.similarity.apply(centre))
    rotation, scale, _ = scan_errors(windowed.similarity, whole.similarity, data)
    assert rotation < 3 * sigma.rotation_deg and scale < 3 * sigma.scale and shift < 3 * sigma.translation
    # Both right: within a tenth of the tolerances (1 degree, 1 %, 0.5 % of the scan's size).
    for result in (windowed, whole):
        rotation, scale, shift = scan_errors(result.similarity, POSE, data)
        assert rotation < 0.1 and scale < 0.001 and shift < 0.0005


def test_a_guess_with_a_known_scale_is_searched_in_a_window():
    data = scan()
    guess = InitialGuess(nudged(POSE, 0.5), rotation_deg=3.0, translation=0.5, scale=0.01)
    result = register(data, MAP, RegistrationConfig(guess=guess))
    assert result.reliable, result.reason
    assert result.window_points is not None
    rotation, scale, shift = scan_errors(result.similarity, POSE, data)
    assert rotation < 0.1 and scale < 0.002 and shift < 0.001


def test_a_wrong_prediction_is_retried_against_the_whole_map():
    """The prediction puts the scan 30 m from where it is: the window holds the wrong part of the
    map, the result is worse than the track, and the scan is retried cold on the whole map
    (here within a budget, which the search does not finish: the answer says it is unreliable,
    and is never a wrong pose called reliable)."""
    data = scan()
    track = register(data, MAP, RegistrationConfig(initial=POSE))
    assert track.reliable and track.window_points is not None
    wrong = Similarity(POSE.scale, POSE.rotation, POSE.translation + np.array([30.0, 0.0, 0.0]))
    result = register(data, MAP, RegistrationConfig(initial=wrong, budget_seconds=1.0), previous=track)
    assert result.retried.startswith("warm start retried cold")
    rotation, scale, shift = scan_errors(result.similarity, POSE, data)
    assert not result.reliable or (rotation < 1.0 and scale < 0.01 and shift < 0.005)


def test_small_models_and_unpredicted_poses_are_not_cut():
    data = scan()
    unknown_scale = InitialGuess(POSE, rotation_deg=3.0, translation=0.5, scale=None)
    assert window_module.window_bounds(data, RegistrationConfig(guess=unknown_scale)) is None
    assert window_module.window_bounds(data, RegistrationConfig()) is None
    small = PreparedModel(TERRAIN.map_points(15_000))
    assert window_module.cut(data[:1000], small, RegistrationConfig(initial=POSE)) is None
    window = window_module.cut(data[:1000], MAP, RegistrationConfig(initial=POSE))
    assert window is not None and 1300 < len(window) < 1700  # thinned to 1.5 times the data
    # A box around the whole map: the whole map, thinned alike.
    everywhere = Similarity(POSE.scale * 20, POSE.rotation, POSE.translation)
    window = window_module.cut(data[:1000], MAP, RegistrationConfig(initial=everywhere))
    assert window is not None and 1300 < len(window) < 1700


def test_windows_keep_the_same_map_points_where_they_overlap():
    """The thinning keeps a point by a key fixed per point: two boxes share their common points'
    selection, and the grid index answers as a pass over every point does."""
    first = PreparedModel(MAP.points)
    low, high = np.array([40.0, 40.0, -10.0]), np.array([60.0, 60.0, 10.0])
    by_pass, count = first.inside(low, high, most=2000)  # the first box: every point tested
    by_grid, again = first.inside(low, high, most=2000)  # later ones: the grid index
    np.testing.assert_array_equal(by_pass, by_grid)
    shifted, _ = first.inside(low + 2.0, high + 2.0, most=2000)
    common = np.intersect1d(by_pass, shifted)
    inside_both = np.all((MAP.points[common] >= low + 2.0) & (MAP.points[common] <= high), axis=1)
    assert count == again and inside_both.all() and common.size > 0.7 * by_pass.size


def test_a_windows_normals_are_the_maps_at_its_rows_and_fitted_once():
    """A window copies its parent's normals and curvatures as they are asked for (its own small
    tables: fewer cache misses than reading the big map's); the values are the map's."""
    whole = PreparedModel(MAP.points)
    rows = np.flatnonzero(
        np.all((MAP.points >= [40.0, 40.0, -10.0]) & (MAP.points <= [60.0, 60.0, 10.0]), axis=1)
    )
    window = whole.subset(rows)
    normals = window.normals(window.tree())
    assert window.normals(window.tree()) is normals  # one table per window
    asked = np.arange(0, len(rows), 7)
    window_normals, window_curvatures = normals.surface(asked)
    map_normals, map_curvatures = whole.normals(whole.tree()).surface(rows[asked])
    np.testing.assert_array_equal(window_normals, map_normals)
    np.testing.assert_array_equal(window_curvatures, map_curvatures)
    np.testing.assert_array_equal(normals[asked[:5]], map_normals[:5])
