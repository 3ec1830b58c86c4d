"""The synthetic scenes of frisicp_bench.structures: what benchmarks/structured_scenes.py builds."""

from __future__ import annotations

import numpy as np

from frisicp_bench.structures import furnished_room, structured_crop_case
from frisicp_core import NearestNeighbors
from frisicp_core.ambiguity import half_turns


def test_two_samplings_of_a_furnished_room_show_the_same_room() -> None:
    # The crop (data) and the scene (model) are independent samplings of one layout: put back by
    # the truth, the crop's points lie on the scene's surfaces (its noise and spacing: 0.3 % of
    # the room's diagonal and a few centimetres), not on another room's.
    case = structured_crop_case("furnished", 0.5, 2.0, np.random.default_rng(3))
    assert case.truth is not None
    distance, _ = NearestNeighbors(case.model).query(case.truth.apply(case.data))
    assert np.median(np.sqrt(distance)) < 0.05
    assert np.quantile(np.sqrt(distance), 0.99) < 0.1


def test_each_case_gets_a_room_of_its_own_without_the_bare_rooms_symmetry() -> None:
    rooms = [furnished_room(np.random.default_rng(seed))(1500.0, np.random.default_rng(9)) for seed in (1, 2)]
    assert not np.allclose(rooms[0].max(axis=0), rooms[1].max(axis=0))
    # A bare box maps onto itself by half turns about its axes (test/core/test_symmetric_scenes.py);
    # the furniture at random places and headings does not: turned, a tenth or more of the room
    # lies off its surfaces.
    room = rooms[0]
    tree = NearestNeighbors(room)
    for turn in half_turns(room):
        distance, _ = tree.query(turn.apply(room))
        assert np.mean(np.sqrt(distance) > 0.1) > 0.1
