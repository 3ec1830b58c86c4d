"""Tracking notices a jump: a warm start left behind by a sudden change of pose is retried cold,
and the better of the two answers wins; a steady track is not retried."""

from __future__ import annotations

import numpy as np
import pytest

from frisicp_core import RegistrationConfig, Similarity, axis_angle_rotation, bumpy_surface, register
from frisicp_core.registration import worse_than_track


def cap(points: np.ndarray, direction: list[float], share: float) -> np.ndarray:
    along = points @ (np.asarray(direction) / np.linalg.norm(direction))
    return points[along >= np.quantile(along, 1.0 - share)]


MAP = bumpy_surface(12000, seed=1)
SCAN = cap(bumpy_surface(12000, seed=2), [1.0, 0.3, 0.2], 0.5)
WHOLE = bumpy_surface(6000, seed=5)  # another sampling of the whole surface
FIRST = Similarity(1.7, axis_angle_rotation([0.2, 0.1, 1.0], 0.3), [0.2, -0.1, 0.4])


def rotation_error_deg(estimate: Similarity, truth: Similarity) -> float:
    return float(np.degrees((estimate @ truth.inverse()).rotation_angle()))


def jumped(jump_deg: float) -> Similarity:
    turn = axis_angle_rotation([1.0, 0.4, -0.3], np.deg2rad(jump_deg))
    return Similarity.about(MAP.mean(axis=0), 1.0, turn) @ FIRST


@pytest.mark.parametrize("jump_deg", [45.0, 120.0, 180.0])
def test_a_warm_start_after_a_jump_is_retried_cold_and_the_cold_answer_wins(jump_deg):
    """A sensor that sees the whole object relocalises: the cold search finds any rotation."""
    track = register(FIRST.inverse().apply(WHOLE), MAP)
    assert track.reliable and rotation_error_deg(track.similarity, FIRST) < 0.5
    second = jumped(jump_deg)
    result = register(
        second.inverse().apply(WHOLE), MAP, RegistrationConfig(initial=track.similarity), previous=track
    )
    if jump_deg > 90.0:  # (from 45 degrees ICP itself slides the whole surface back)
        assert result.retried.startswith("warm start retried cold") and not result.warm_started
    assert result.reliable, result.reason
    assert rotation_error_deg(result.similarity, second) < 1.0


@pytest.mark.parametrize("jump_deg", [60.0, 120.0, 180.0])
def test_a_jump_the_cold_search_cannot_follow_is_not_reliable(jump_deg):
    """Half of the surface turned far from where the track was: the warm start is rejected, and
    where the cold search cannot find the pose either, the answer says so instead of guessing."""
    track = register(FIRST.inverse().apply(SCAN), MAP)
    second = jumped(jump_deg)
    result = register(
        second.inverse().apply(SCAN), MAP, RegistrationConfig(initial=track.similarity), previous=track
    )
    assert result.retried.startswith("warm start retried cold")
    assert result.reliable == (rotation_error_deg(result.similarity, second) < 1.0), result.reason


def test_a_steady_track_is_not_retried():
    track = register(FIRST.inverse().apply(SCAN), MAP)
    nudge = Similarity.about(MAP.mean(axis=0), 1.01, axis_angle_rotation([0.0, 0.0, 1.0], np.deg2rad(2.0)))
    second = nudge @ FIRST
    result = register(
        second.inverse().apply(SCAN), MAP, RegistrationConfig(initial=track.similarity), previous=track
    )
    assert result.retried == "" and result.warm_started and result.reliable
    assert rotation_error_deg(result.similarity, second) < 0.5
    assert worse_than_track(result, track) == ""
