"""Symmetric scenes: a crop of a room that a half turn maps onto itself fits at the half-turned
pose as well as at the true one, so the answer is ambiguous whichever the search returns.

The scenes are frisicp_bench.structures' (benchmarks/structured_scenes.py measures all of them);
the data and the model are independent samplings, as two sensors' are.
"""

from __future__ import annotations

import numpy as np
import pytest

from frisicp_bench.structures import structured_crop_case, structured_scene
from frisicp_core import NearestNeighbors, downsample, register, rotation_angle
from frisicp_core.ambiguity import half_turns, merit_noise
from frisicp_core.overlap import select_pairs


def test_a_half_turn_about_the_halls_vertical_axis_maps_it_onto_itself() -> None:
    hall = structured_scene("hall", np.random.default_rng(0))
    tree = NearestNeighbors(hall)
    # Each turn about a principal axis of a box-shaped room maps its walls onto its walls: the
    # turned points lie within a few centimetres (the sampling's spacing) of the room's.
    for turn in half_turns(hall):
        distance, _ = tree.query(turn.apply(hall))
        assert np.degrees(rotation_angle(turn.rotation)) == pytest.approx(180.0)
        assert np.sqrt(np.max(distance)) < 0.1


@pytest.mark.parametrize("share", [0.2, 0.4, 0.9])
def test_the_merit_noise_bounds_how_much_merits_of_other_samplings_spread(share: float) -> None:
    # 2,000 pairs, ``share`` of them on the surface (distances of a few noise sigmas), the rest
    # far: what merit_noise says of one draw is about the spread of log sqrt(psi) over fresh
    # draws (0.045 against 0.042 at 40 %), and never much below it (twice it at 20 %).
    rng = np.random.default_rng(1)
    logs, predicted = [], []
    for _ in range(400):
        inlier = rng.random(2000) < share
        dist_sq = np.where(inlier, 0.01 * rng.chisquare(3, 2000), 1.0 + rng.random(2000))
        selection = select_pairs(dist_sq[None], np.zeros(1), None, None)
        logs.append(0.5 * np.log(selection.merit[0]))
        predicted.append(merit_noise((selection,)))
    assert 0.9 * np.std(logs) < np.median(predicted) < 2.1 * np.std(logs)


def _registered(kind: str, share: float, seed: int, reverse: bool):  # type: ignore[no-untyped-def]
    rng = np.random.default_rng(seed)
    case = structured_crop_case(kind, share, 2.0, rng, reverse=reverse)
    data, model = downsample(case.data, 5000, rng), downsample(case.model, 5000, rng)
    return register(data, model)


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_the_tables_hall_onto_its_crop_is_ambiguous_with_the_half_turn_as_competitor(seed: int) -> None:
    # Seeds 1 and 2 came out right and reliable before the answer's twins were probed: right
    # only by luck, since the half-turned room fits the crop as well. Seed 3 came out half-turned
    # and reliable with the twins probed: its twin (the truth) measured 15 % worse than the
    # answer on the thinned points ICP ended on, and 2 % on all of them, where it is now judged.
    result = _registered("tables", 0.5, seed, reverse=True)
    assert not result.reliable
    assert result.reason.startswith("ambiguous")
    assert result.competitor is not None
    turn = np.degrees(rotation_angle(result.competitor.similarity.rotation @ result.similarity.rotation.T))
    assert turn == pytest.approx(180.0, abs=2.0)


@pytest.mark.parametrize("seed", [0, 3])
def test_a_crop_of_a_shelf_rack_is_not_reliable(seed: int) -> None:
    # Both seeds came out wrong and reliable before: seed 0 one bay (1 m) along the rack, seed 3
    # half-turned. The rack is the same half-turned and a bay along.
    result = _registered("shelves", 0.5, seed, reverse=False)
    assert not result.reliable
    assert "ambiguous" in result.reason


def test_an_exact_copy_of_a_grid_cloud_is_ambiguous_with_its_half_turn_not_a_crash() -> None:
    # Integer grid points registered onto themselves: the answer and its half turn both fit
    # exactly (merit 0), which once divided by zero (ZeroDivisionError out of register).
    grid = np.stack(np.meshgrid(np.arange(20.0), np.arange(15.0), np.arange(3.0)), axis=-1).reshape(-1, 3)
    grid = grid[np.random.default_rng(0).permutation(len(grid))]
    result = register(grid, grid)
    assert not result.reliable
    assert result.reason.startswith("ambiguous")
    assert result.competitor is not None and result.competitor.merit_ratio == 1.0
    assert np.degrees(rotation_angle(result.competitor.similarity.rotation)) == pytest.approx(180.0)
