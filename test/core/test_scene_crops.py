"""A small crop of a real scene registered onto the scene: where the merit and the fit disagree.

TrICP's merit rewards explaining more of each cloud, so a 10 % crop swollen over half of its
scene at six times the residuals can score lower than the crop laid where it belongs. The
search then keeps the pose with the lowest merit among those that fit clearly
(frisicp_core.solver.compare_finalists)."""

from __future__ import annotations

import zlib

import numpy as np
import pytest
from support.data import SHARED_DATA, shared_file

from frisicp_bench import scenes
from frisicp_bench.cases import PAPER_SCALES
from frisicp_bench.metrics import pose_errors
from frisicp_core import downsample, register


def assert_found(suite: str, index: int, share: float, scale: float, reverse: bool = False) -> None:
    """benchmarks/trustworthy.py's dragon case ``suite``/``index`` (both clouds capped at 10,000
    points, its seed) is registered right, and reliable or refused only for a rival within the
    ambiguity margin."""
    shared_file("real/dragon1.xyz")
    rng = np.random.default_rng(zlib.crc32(f"{suite}/dragon1.xyz/{index}/10000".encode()))
    scene = scenes.object_cloud(SHARED_DATA, "dragon1.xyz")
    assert float(rng.choice(PAPER_SCALES)) == scale
    case = scenes.crop_case(scene, "dragon1.xyz", share, scale, rng, reverse=reverse)
    data, model = downsample(case.data, 10_000, rng), downsample(case.model, 10_000, rng)
    result = register(data, model)
    assert case.truth is not None
    errors = pose_errors(result.similarity, case.truth, data, case.model_diagonal)
    assert errors.rotation_deg < 1.0 and errors.scale < 0.01 and errors.translation < 0.005
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
