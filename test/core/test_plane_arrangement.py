"""Starting poses from the arrangement of large planes (frisicp_core.plane_arrangement): a room's
walls and floor give its directions, their offsets its scale and shift; a smooth object gives
nothing, and its registrations are as before."""

from __future__ import annotations

import numpy as np

from frisicp_bench.metrics import pose_errors
from frisicp_bench.structures import box_surface, seeded_case
from frisicp_core.plane_arrangement import _profile_fit, _ScaledProfiles, plane_starts
from frisicp_core.plane_directions import plane_directions
from frisicp_core.prepared import PreparedModel


def test_a_rooms_walls_floor_and_ceiling_are_its_three_dominant_directions() -> None:
    rng = np.random.default_rng(0)
    room = box_surface((0.0, 0.0, 0.0), (6.0, 4.5, 2.7), 300.0, rng)
    room += rng.normal(scale=0.01, size=room.shape)
    found = plane_directions(room)
    assert len(found.directions) == 3
    # Each within 0.3 degrees of a coordinate axis (sign-free), one per axis.
    alignment = np.abs(found.directions @ np.eye(3))
    assert np.all(alignment.max(axis=1) > np.cos(np.deg2rad(0.3)))
    assert sorted(np.argmax(alignment, axis=1)) == [0, 1, 2]
    # The floor and ceiling (6 x 4.5 twice) hold the largest share of the normals.
    assert np.argmax(alignment[np.argmax(found.shares)]) == 2
    assert found.strong == 3


def test_a_smooth_object_has_no_dominant_direction_and_gets_no_plane_starts() -> None:
    rng = np.random.default_rng(1)
    sphere = rng.normal(size=(8000, 3))
    sphere /= np.linalg.norm(sphere, axis=1, keepdims=True)
    assert len(plane_directions(sphere).directions) == 0
    assert plane_starts(0.5 * sphere, PreparedModel(sphere)) == []


def test_a_profile_of_plane_offsets_gives_the_scale_and_the_shift() -> None:
    # Planes at four offsets, the data's at half the model's scale and shifted: model = 2 data + 0.3.
    rng = np.random.default_rng(2)
    model = np.repeat([0.0, 1.0, 2.5, 4.0], 200) + rng.normal(scale=0.005, size=800)
    data = (model - 0.3) / 2.0
    scales = 2.0 * 2.0 ** (np.arange(-16, 17) / 16)
    fit = _profile_fit(_ScaledProfiles.of(data, scales, 0.04), model, width=0.04)
    best = int(np.argmax(fit.best()))
    assert scales[best] == 2.0
    assert abs(fit.translations(best, 1)[0] - 0.3) < 0.04  # one bin
    assert fit.best()[best] > 0.95
    # Squeezed to a twentieth, the data would lie on one peak: it overlaps too little of the
    # model's profile to score at all.
    squeezed = _profile_fit(_ScaledProfiles.of(data, np.array([0.1]), 0.04), model, width=0.04)
    assert squeezed.best()[0] == 0.0


def test_a_room_onto_a_third_of_it_gets_a_start_at_the_truth_from_its_planes() -> None:
    # structured_scenes.py --kinds furnished's case "furnished 30% s=0.5" of draw 0, the room onto
    # a 30 % crop of it: the descriptors found no start within 50 degrees of the truth.
    case, data, model = seeded_case("furnished", 0.3, "scene onto crop", 0, draw=0, cap=10_000)
    assert case.name == "furnished 30% s=0.5" and case.truth is not None
    starts = plane_starts(data, PreparedModel(model))
    errors = pose_errors(starts[0], case.truth, data, case.model_diagonal)
    assert errors.rotation_deg < 1.0 and errors.scale < 0.02 and errors.translation < 0.02
