"""A sparse map (2,000 noisy points, 10 % outliers, unknown scale) onto a dense scene: the
search's comparison also tries its best poses shrunk, because a trimmed merit rewards a map
swollen over more of the scene than it covers (frisicp_core.registration.shrunk_starts)."""

from __future__ import annotations

import zlib

import numpy as np
import pytest
from support.data import SHARED_DATA, shared_file

from frisicp_bench import scenes
from frisicp_bench.cases import PAPER_SCALES
from frisicp_bench.metrics import pose_errors
from frisicp_core import RegistrationConfig, Similarity, downsample, register
from frisicp_core.registration import shrunk_starts
from frisicp_core.rotations import exp_rotation


def test_a_shrunk_start_is_the_pose_half_an_octave_smaller_where_it_puts_the_data_centre():
    pose = Similarity(3.0, exp_rotation(np.array([0.1, -0.4, 0.2]), 3), np.array([1.0, -2.0, 0.5]))
    centre = np.array([0.3, 0.2, -0.1])
    (shrunk,) = shrunk_starts([pose], centre)
    assert shrunk.scale == pytest.approx(3.0 / np.sqrt(2.0), rel=1e-12)
    np.testing.assert_allclose(shrunk.rotation, pose.rotation, atol=1e-12)
    np.testing.assert_allclose(shrunk.apply(centre), pose.apply(centre), atol=1e-12)
    # Every other point is pulled towards the centre's image by the same factor.
    other = centre + np.array([1.0, 0.0, 0.0])
    np.testing.assert_allclose(
        shrunk.apply(other) - shrunk.apply(centre), (pose.apply(other) - pose.apply(centre)) / np.sqrt(2.0)
    )


def swollen_sparse_map() -> tuple[scenes.SceneCase, np.ndarray, np.ndarray]:
    """benchmarks/trustworthy.py's case "dragon2.xyz sparse s=3.05" of ``--draw 2``, both clouds
    capped at 10,000 points."""
    shared_file("real/dragon2.xyz")
    rng = np.random.default_rng(zlib.crc32(b"sparse map onto scene/dragon2.xyz/1/10000/draw 2"))
    case = scenes.sparse_map_case(scenes.object_cloud(SHARED_DATA, "dragon2.xyz"), "dragon2.xyz", rng)
    assert case.name == "dragon2.xyz sparse s=3.05" and case.truth is not None
    return case, downsample(case.data, 10_000, rng), downsample(case.model, 10_000, rng)


@pytest.mark.real_data
@pytest.mark.parametrize("shrink", [0.71, 0.84])
def test_starts_at_the_truth_shrunk_and_turned_30_degrees_return_to_it(shrink: float):
    """Why shrinking works: below the truth's scale its basin is wide. (Warm starts at the
    truth swollen by 1.41 end 30-40 % too large on this map, where the screened poses were.)"""
    case, data, model = swollen_sparse_map()
    assert case.truth is not None
    centre = case.truth.apply(data.mean(axis=0))
    turn = exp_rotation(np.deg2rad(30.0) * np.array([0.6, -0.48, 0.64]), 3)
    start = Similarity.about(centre, shrink, turn) @ case.truth
    result = register(data, model, RegistrationConfig(initial=start))
    errors = pose_errors(result.similarity, case.truth, data, case.model_diagonal)
    assert result.retried == "", result.retried  # the warm start itself, not a cold retry
    assert errors.rotation_deg < 1.0 and errors.scale < 0.01 and errors.translation < 0.005
    assert result.reliable, result.reason


@pytest.mark.real_data
def test_a_sparse_map_whose_screened_poses_are_all_swollen_is_found_from_below():
    """benchmarks/trustworthy.py's case "dragon2.xyz sparse s=3.05" of ``--draw 2`` (both clouds
    capped at 10,000 points; found on that held-out run, so now a development case): every pose
    the screening put forward came out 20-38 % too large and 5-8 degrees off (the descriptor
    search's, 37 degrees and more), and ICP on the first dense level kept them there (RMS 0.69,
    refused as a misfit with a rival). Shrunk by half an octave, two of them land a little below
    the truth's scale and return to it: right and reliable (its start at the truth is both)."""
    case, data, model = swollen_sparse_map()
    result = register(data, model)
    errors = pose_errors(result.similarity, case.truth, data, case.model_diagonal)
    assert errors.rotation_deg < 1.0 and errors.scale < 0.01 and errors.translation < 0.005
    assert result.reliable, result.reason


@pytest.mark.real_data
def test_a_shrunk_start_that_loses_the_comparison_is_no_rival_of_the_answer():
    """benchmarks/trustworthy.py's case "bunny_part2.xyz 20% s=2.3" of ``--draw 3`` (crop onto
    scene, both capped at 10,000 points; held-out, now a development case). Its start at the
    truth is right and refused (the data do not determine it to the tolerance). When shrunk
    starts were also nominated as rivals, one 93 degrees off was run down the levels by the
    probes and replaced the answer: wrong (85 degrees), refused. Shrunk starts may win the
    comparison, but only the answer's own runners-up are run down as rivals."""
    shared_file("real/bunny_part2.xyz")
    rng = np.random.default_rng(zlib.crc32(b"crop onto scene/bunny_part2.xyz/8/10000/draw 3"))
    scene = scenes.object_cloud(SHARED_DATA, "bunny_part2.xyz")
    case = scenes.crop_case(scene, "bunny_part2.xyz", 0.2, float(rng.choice(PAPER_SCALES)), rng)
    assert case.name == "bunny_part2.xyz 20% s=2.3" and case.truth is not None
    data, model = downsample(case.data, 10_000, rng), downsample(case.model, 10_000, rng)
    result = register(data, model)
    errors = pose_errors(result.similarity, case.truth, data, case.model_diagonal)
    assert errors.rotation_deg < 1.0 and errors.scale < 0.01 and errors.translation < 0.005
    assert not result.reliable  # 3 sigma of the rotation is about 2.7 degrees
