"""A small crop of a real scene registered onto the scene: where the merit and the fit disagree.

TrICP's merit rewards explaining more of each cloud, so a 10 % crop swollen over half of its
scene at six times the residuals can score lower than the crop laid where it belongs. The
search then keeps the pose with the lowest merit among those that fit clearly
(frisicp_core.solver.compare_finalists); a pose that fits but not clearly, where ICP crawled to a
stop short of its minimum, is finished by the point-to-plane steps and judged again."""

from __future__ import annotations

import zlib

import numpy as np
import pytest
from support.data import SHARED_DATA, shared_file

from frisicp_bench import scenes
from frisicp_bench.cases import PAPER_SCALES
from frisicp_bench.metrics import PoseErrors, pose_errors
from frisicp_core import RegistrationConfig, RegistrationResult, downsample, register


def registered(
    suite: str,
    index: int,
    share: float,
    scale: float,
    reverse: bool = False,
    scene_file: str = "dragon1.xyz",
    cap: int = 10_000,
    draw: int = 0,
    from_truth: bool = False,
) -> tuple[RegistrationResult, PoseErrors]:
    """benchmarks/trustworthy.py's case ``suite``/``scene_file``/``index`` (both clouds capped at
    ``cap`` points, 0: full resolution; its seed, salted by ``draw``) registered, cold or
    ``from_truth`` (warm; ``register`` retries an unreliable warm start cold and keeps the
    better, so where the cold answer is refused, as in :func:`assert_found`, the result is
    reliable only if the start at the truth is), and its errors."""
    shared_file(f"bunny/{scene_file}" if scene_file.startswith("bun") else f"real/{scene_file}")
    salt = f"/draw {draw}" if draw else ""
    rng = np.random.default_rng(zlib.crc32(f"{suite}/{scene_file}/{index}/{cap}{salt}".encode()))
    scene = scenes.object_cloud(SHARED_DATA, scene_file)
    assert float(rng.choice(PAPER_SCALES)) == scale
    case = scenes.crop_case(scene, scene_file, share, scale, rng, reverse=reverse)
    data, model = case.data, case.model
    if cap:
        data, model = downsample(data, cap, rng), downsample(model, cap, rng)
    assert case.truth is not None
    result = register(
        data, model, RegistrationConfig(initial=case.truth) if from_truth else RegistrationConfig()
    )
    return result, pose_errors(result.similarity, case.truth, data, case.model_diagonal)


def assert_found(suite: str, index: int, share: float, scale: float, reverse: bool = False) -> None:
    """The dragon's case (:func:`registered`) is registered right, and reliable, or refused only
    for a rival within the ambiguity margin, or for sigmas past the tolerance as the truth itself
    is when started there (the split halves draw from their own stream, so both are sized alike)."""
    result, errors = registered(suite, index, share, scale, reverse)
    assert errors.rotation_deg < 1.0 and errors.scale < 0.01 and errors.translation < 0.005
    if result.reason.startswith("not determined"):
        at_truth, _ = registered(suite, index, share, scale, reverse, from_truth=True)
        assert at_truth.reason.startswith("not determined"), (result.reason, at_truth.reason)
    else:
        assert result.reliable or result.reason.startswith("ambiguous:"), result.reason


@pytest.mark.real_data
def test_a_ten_percent_crop_of_the_dragon_at_a_tenth_of_its_size_is_found_where_it_belongs():
    """benchmarks/trustworthy.py's case "dragon1.xyz 10% s=0.1" (both clouds capped at 10,000
    points): with the merit alone the answer was turned 177 degrees and 2.4 times too large, refused;
    the crop's true place fits with 2-3 % near misses and is found, right and reliable.

    Whether a probe also turns up a rival within the ambiguity margin here hangs on the last
    digits: with the descriptors' normals changed in the 16th digit (another eigen solver) a
    rival at a merit ratio of 1.044 appeared (the margin is 1.05) and the right answer was
    refused as ambiguous. So the test asks for the right pose, reliable or refused for such a
    rival, never for a misfit; a different BLAS/LAPACK build must not flip it."""
    assert_found("crop onto scene", 1, 0.1, 0.1)


@pytest.mark.real_data
def test_the_whole_dragon_is_found_in_a_third_of_it():
    """benchmarks/trustworthy.py's case "scene onto crop dragon1.xyz 30% s=2.1" (both clouds
    capped at 10,000 points): the whole dragon onto a re-sampled noisy crop of 30 % of it, at
    2.1 times its size. The global search matches the data's local shapes onto the model's;
    most of the whole dragon's shapes have no counterpart in the crop, and its poses were all
    wrong (the answer 73 degrees off, refused). The same search the other way, the crop's shapes
    onto the dragon's, finds the crop's place, so the answer is right (reliable, or refused only
    for a rival within the ambiguity margin, as above)."""
    assert_found("scene onto crop", 1, 0.3, 2.1, reverse=True)


@pytest.mark.real_data
def test_a_ten_percent_crop_of_a_room_at_full_resolution_is_finished_where_icp_stopped_short():
    """benchmarks/trustworthy.py's case "rs1.pcd 10% s=2.9" at full resolution (18,559 points
    onto 289,541): the descriptor search's best start lay 5 degrees off the truth, but ICP on the
    first dense level crawled to a stop 4.4 degrees off with 29 % near misses (not a clear fit),
    and a pose turned 90 degrees and swollen over the room, with the lowest merit and 65 % near
    misses, was the answer (refused). Finished by the point-to-plane steps, the start ends a few
    tenths of a degree off with 13 % near misses and wins: the answer is right. Its scale is
    known to about 0.3 % (1 sigma), so it may be refused as not determined to the 1 % tolerance
    at 3 sigma, never for a misfit."""
    result, errors = registered("crop onto scene", 1, 0.1, 2.9, scene_file="rs1.pcd", cap=0)
    assert errors.rotation_deg < 1.0 and errors.scale < 0.01 and errors.translation < 0.005
    assert result.reliable or result.reason.startswith(("ambiguous:", "not determined")), result.reason


@pytest.mark.real_data
def test_the_whole_dragon_shrunk_into_a_tenth_of_it_does_not_stop_the_search_the_other_way():
    """benchmarks/trustworthy.py's case "scene onto crop dragon1.xyz 10% s=2.3" of ``--draw 1``:
    no pose of the data's search fitted clearly; finished, one shrunk the whole dragon 7 times
    into its 10 % crop, 95 degrees off, and fitted (near misses <= 25 %). An answer that fits only
    once finished still lets the swapped search (the crop's shapes onto the dragon's) have its
    say, and the crop's true place wins: right, refused only because 3 sigma of its rotation
    (about 1.4 degrees) exceed the tolerance, or for a rival."""
    result, errors = registered("scene onto crop", 4, 0.1, 2.3, reverse=True, draw=1)
    assert errors.rotation_deg < 1.0 and errors.scale < 0.01 and errors.translation < 0.005
    assert result.reliable or result.reason.startswith(("ambiguous:", "not determined")), result.reason


@pytest.mark.real_data
def test_a_fifth_of_the_dragon_is_found_through_the_matches_that_agree():
    """benchmarks/trustworthy.py's case "dragon1.xyz 20% s=2.5" (both clouds capped at 10,000
    points): at the right rung of the descriptor search 25 of 1,974 matches are right, and the
    40,000 random triples held no three of them; the answer was turned 170 degrees (refused).
    The matches' agreement graph (frisicp_core.compatibility) ranks pairs of right matches
    first, and the crop is found: right and reliable (or refused only for a rival)."""
    assert_found("crop onto scene", 2, 0.2, 2.5)


@pytest.mark.real_data
def test_a_crop_swollen_over_the_scene_is_no_rival_to_a_clear_fit():
    """benchmarks/trustworthy.py's case "bun_zipper.ply 20% s=2.3" at full resolution: the
    answer is right and leaves 1.5 % near misses; two runners-up of the search, swollen 1.7
    times over the bunny and turned 69 and 161 degrees, match its merit within 1-2 % but leave
    75 % near misses (they fail the fit check). They do not make the answer ambiguous."""
    result, errors = registered("crop onto scene", 8, 0.2, 2.3, scene_file="bun_zipper.ply", cap=0)
    assert errors.rotation_deg < 1.0 and errors.scale < 0.01 and errors.translation < 0.005
    assert not result.reason.startswith("ambiguous"), result.reason
    assert result.competitor is None


@pytest.mark.real_data
def test_a_crop_that_seems_to_cover_its_scene_only_at_a_misfit_is_still_searched():
    """benchmarks/trustworthy.py's case "dragon2.xyz 30% s=1.1" of ``--draw 3`` (both clouds
    capped at 10,000 points; found on that held-out run, so now a development case): the
    moments' best pose swelled the crop 47 % over the scene, 15 degrees off, where both overlap
    estimates said the clouds covered each other, so the descriptor search was skipped and the
    misfit refused. An answer that covers but does not fit asks the search as well: its starts
    lie 1-7 degrees off, and the crop is found, right and reliable."""
    result, errors = registered("crop onto scene", 3, 0.3, 1.1, scene_file="dragon2.xyz", draw=3)
    assert errors.rotation_deg < 1.0 and errors.scale < 0.01 and errors.translation < 0.005
    assert result.reliable, result.reason


@pytest.mark.real_data
def test_a_flat_five_percent_crop_started_at_the_truth_is_refused_not_a_crash():
    """benchmarks/trustworthy.py's case "rs1.pcd 5% s=2.9" of ``--draw 1`` (both clouds capped at
    10,000 points), started at the truth: a nearly flat patch does not fix the scale about its
    centre, and a split half's Gauss-Newton step, held by the damping alone, took the scale x250;
    re-paired there, the next step went past 1e308 and ``register`` raised ValueError. A half
    whose steps run off (frisicp_core.refine.Polished.ran_off) leaves the scale undetermined:
    the result is refused, or right."""
    result, errors = registered(
        "crop onto scene", 6, 0.05, 2.9, scene_file="rs1.pcd", draw=1, from_truth=True
    )
    assert errors.success or not result.reliable, result.reason
