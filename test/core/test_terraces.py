"""Two frames of a depth camera with coarse depth steps are registered as their averages over a
step's voxels; anything else is registered as given."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from support.depth_camera import quantised, room_corner

from frisicp_core import (
    PreparedModel,
    RegistrationConfig,
    Similarity,
    Tolerance,
    axis_angle_rotation,
    register,
    voxel_centroids,
)
from frisicp_core.terraces import AVERAGE_STEPS, average_terraces

STEP = 0.06  # at 3 m: about 1.7 % of the corner's size, a coarse camera


def frames(seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Two samplings of one corner by one camera, each in the camera's frame: the truth is the
    identity."""
    rng = np.random.default_rng(seed)
    return quantised(room_corner(rng, 15_000), STEP, "z", rng), quantised(
        room_corner(rng, 15_000), STEP, "z", rng
    )


def test_two_coarse_frames_are_registered_as_their_averages():
    data, model = frames(0)
    result = register(data, model)
    assert result.depth_averaged is not None
    data_edge, model_edge = result.depth_averaged
    # A step at each cloud's own median depth (about 3 m: the step there).
    assert data_edge == pytest.approx(AVERAGE_STEPS * STEP, rel=0.05)
    assert model_edge == pytest.approx(AVERAGE_STEPS * STEP, rel=0.05)
    averaged = voxel_centroids(data, data_edge)
    assert result.levels[-1].data_points == averaged.shape[0] < 0.3 * data.shape[0]
    # Right, or not called reliable.
    if result.reliable:
        assert np.degrees(result.similarity.rotation_angle()) < 1.0
        assert abs(result.similarity.scale - 1.0) < 0.01


def test_clouds_without_steps_on_both_sides_are_registered_as_given():
    data, model = frames(1)
    smooth = room_corner(np.random.default_rng(2), 15_000)
    assert register(data, smooth).depth_averaged is None  # a frame onto a map: no terraces to lock
    assert register(smooth, model).depth_averaged is None
    # Turned out of the camera's frame, the shells are no planes of the clouds' axes.
    turned = Similarity(
        1.0, axis_angle_rotation([1.0, 1.0, 0.0], np.radians(35.0)), np.array([0.3, -2.0, 1.0])
    )
    assert register(turned.apply(data), turned.apply(model)).depth_averaged is None
    # Switched off, and in the paper's algorithm.
    assert register(data, model, RegistrationConfig(average_depth_steps=False)).depth_averaged is None
    assert RegistrationConfig.paper().average_depth_steps is False


def test_a_prepared_model_averages_once_and_answers_as_its_array():
    data, model = frames(3)
    prepared = PreparedModel(model)
    first = register(data, prepared)
    again = register(data, prepared)
    as_array = register(data, model)
    assert first.depth_averaged == again.depth_averaged == as_array.depth_averaged is not None
    assert prepared.averaged(first.depth_averaged[1]) is prepared.averaged(first.depth_averaged[1])
    assert np.array_equal(first.similarity.matrix(), as_array.similarity.matrix())
    assert first.reliable == as_array.reliable


def test_the_edges_are_in_each_clouds_own_units():
    data, model = frames(4)
    # The data in millimetres, the model in metres: each averaged over its own step.
    result = register(1000.0 * data, model)
    assert result.depth_averaged is not None
    assert result.depth_averaged[0] == pytest.approx(1000.0 * AVERAGE_STEPS * STEP, rel=0.05)
    assert result.depth_averaged[1] == pytest.approx(AVERAGE_STEPS * STEP, rel=0.05)
    assert result.similarity.scale == pytest.approx(1e-3, rel=0.02)


def test_two_dimensional_clouds_have_no_depth_steps():
    rng = np.random.default_rng(5)
    contour = rng.uniform(1.0, 2.0, size=(600, 2))
    assert average_terraces(contour, PreparedModel(contour)) is None


def test_what_the_voxel_grid_moves_widens_the_uncertainty_and_can_refuse():
    # The same averages registered directly (no averaging in the core) answer the same pose,
    # but only the core's own average adds what grids half a voxel apart move: d d^T.
    data, model = frames(0)
    prepared = PreparedModel(model)
    loose = RegistrationConfig(tolerance=Tolerance(rotation_deg=10.0, scale=0.1, translation=0.1))
    averaged = register(data, prepared, loose)
    assert averaged.reliable and averaged.depth_averaged is not None
    data_edge, model_edge = averaged.depth_averaged
    direct = register(
        voxel_centroids(data, data_edge),
        prepared.averaged(model_edge),
        replace(loose, average_depth_steps=False),
    )
    assert np.array_equal(direct.similarity.matrix(), averaged.similarity.matrix())
    added = averaged.covariance - direct.covariance
    eigenvalues = np.linalg.eigvalsh(added)
    assert eigenvalues[-1] > 0 and np.all(eigenvalues[:-1] < 1e-12 * eigenvalues[-1])  # one direction
    # A scale tolerance the direct answer just meets, the widened one does not. A tolerance
    # that near its sigmas has them sized by more split halves (frisicp_core.refine.BORDERLINE):
    # the direct answer's sigma as judged by a tolerance in that band.
    near = replace(loose, tolerance=replace(loose.tolerance, scale=3.0 * direct.uncertainty.scale))
    sized = register(
        voxel_centroids(data, data_edge),
        prepared.averaged(model_edge),
        replace(near, average_depth_steps=False),
    )
    tight = replace(loose, tolerance=replace(loose.tolerance, scale=3.0001 * sized.uncertainty.scale))
    assert register(
        voxel_centroids(data, data_edge),
        prepared.averaged(model_edge),
        replace(tight, average_depth_steps=False),
    ).reliable
    refused = register(data, prepared, tight)
    assert not refused.reliable
    assert refused.reason.startswith("averaged over a depth step's voxels, on grids half a voxel apart")
    assert "3 sigma of the scale" in refused.reason
