"""Depth steps: a depth camera's quantised shells are found, with their spacing; surfaces are not."""

from __future__ import annotations

import numpy as np
import pytest
from support.data import shared_file
from support.depth_camera import MEDIAN_DEPTH_GUESS, quantised, room_corner

from frisicp_core import PreparedModel, read_points
from frisicp_core.depth_steps import COARSE_SHARE, find_depth_steps


def expected_step(points: np.ndarray, step: float, depth: str) -> float:
    """The step at the cloud's own median depth (it grows with the depth squared)."""
    measure = points[:, 2] if depth == "z" else np.linalg.norm(points, axis=1)
    return step * (float(np.median(measure)) / MEDIAN_DEPTH_GUESS) ** 2


@pytest.mark.parametrize("depth", ["z", "range"])
@pytest.mark.parametrize("noise", [0.0, 0.1])
def test_a_depth_cameras_shells_are_found_with_their_spacing(depth, noise):
    rng = np.random.default_rng(1)
    step = 0.06  # about 1.7 % of the room corner's 3.5 m diagonal: coarse
    cloud = quantised(room_corner(rng), step, depth, rng, noise)
    found = find_depth_steps(cloud)
    assert found is not None
    assert found.depth == depth
    assert found.step == pytest.approx(expected_step(cloud, step, depth), rel=0.02)
    assert found.share == pytest.approx(found.step / np.linalg.norm(np.ptp(cloud, axis=0)))
    assert found.coarse
    assert found.coherence > (0.99 if noise == 0 else 0.7)  # exp(-2 pi^2 0.1^2) = 0.82
    assert "depth steps of 0.0" in str(found)


def test_shells_blurred_by_over_a_quarter_of_their_spacing_are_still_found():
    """A stereo camera's noise blurs the shells (here 0.27 of their spacing: a coherence of 0.27,
    under the floor of 0.3 the finder once had); blurred terraces still lock two frames
    (benchmarks/depth_sensor.py --noise 0.005), so they are found."""
    rng = np.random.default_rng(8)
    cloud = quantised(room_corner(rng), 0.06, "z", rng, noise=0.27)
    found = find_depth_steps(cloud)
    assert found is not None and found.coarse
    assert found.step == pytest.approx(expected_step(cloud, 0.06, "z"), rel=0.02)
    assert 0.2 < found.coherence < 0.3


@pytest.mark.parametrize(
    "relative", ["real/chef.pcd", "real/dragon2.xyz", "bunny/bun270.ply", "bunny/bun_zipper_res2.ply"]
)
def test_real_objects_seen_from_anywhere_in_front_show_no_shells(relative):
    """Clouds with no quantised depth, seen from 8 random places in front of them, 2,000 and all
    their points: none shows shells (at a floor of 0.1 two did: the decimated bunny at 0.13-0.19,
    bun270 at 0.10)."""
    cloud = read_points(shared_file(relative))
    rng = np.random.default_rng(9)
    diagonal = float(np.linalg.norm(np.ptp(cloud, axis=0)))
    for _ in range(8):
        direction = rng.normal(size=3)
        sensor = cloud.mean(axis=0) + direction / np.linalg.norm(direction) * diagonal * rng.uniform(0.7, 3.0)
        for points in (cloud[rng.choice(len(cloud), 2000, replace=False)], cloud):
            assert find_depth_steps(points - sensor) is None


def test_a_prepared_model_looks_for_its_shells_once():
    rng = np.random.default_rng(7)
    cloud = quantised(room_corner(rng), 0.06, "z", rng)
    model = PreparedModel(cloud)
    found = model.depth_steps
    assert found is not None and found.coarse and found.depth == "z"
    assert found.step == pytest.approx(expected_step(cloud, 0.06, "z"), rel=0.02)
    assert model.depth_steps is found  # kept, not looked for again
    assert PreparedModel(room_corner(rng)).depth_steps is None


def test_fine_shells_are_found_but_not_coarse():
    rng = np.random.default_rng(2)
    cloud = quantised(room_corner(rng), 0.012, "z", rng)  # 0.3 % of the diagonal
    found = find_depth_steps(cloud)
    assert found is not None and found.share < COARSE_SHARE
    assert found.step == pytest.approx(expected_step(cloud, 0.012, "z"), rel=0.02)


def test_a_few_shells_deep_the_spacing_is_not_taken_for_half_of_it():
    # A plane 2.9-3.1 m away, across 3.3 shells: a broad peak at the shells' frequency, a
    # narrow one at twice it.
    rng = np.random.default_rng(6)
    n = 20_000
    u, v = rng.uniform(-1.0, 1.0, size=(2, n))
    plane = np.column_stack([0.6 * u, 0.4 * v, 3.0 + 0.1 * u])
    cloud = quantised(plane, 0.06, "z", rng)
    found = find_depth_steps(cloud)
    assert found is not None and found.shells < 4
    assert found.step == pytest.approx(expected_step(cloud, 0.06, "z"), rel=0.05)


def test_shells_buried_in_noise_are_not_reported():
    rng = np.random.default_rng(3)
    cloud = quantised(room_corner(rng), 0.06, "z", rng, noise=0.5)  # coherence exp(-2 pi^2 / 4) = 0.007
    assert find_depth_steps(cloud) is None


def test_surfaces_without_shells_are_not_reported():
    rng = np.random.default_rng(4)
    room = room_corner(rng)
    assert find_depth_steps(room + rng.normal(scale=0.002, size=room.shape)) is None
    # One wall facing the camera is a single shell (every depth equal, up to the noise), two
    # walls two of them: broad peaks, no comb.
    n = 20_000
    wall = np.column_stack(
        [rng.uniform(-1, 1, n), rng.uniform(-1, 1, n), 2.5 + rng.normal(scale=0.001, size=n)]
    )
    assert find_depth_steps(wall) is None
    farther = wall + np.array([0.0, 0.0, 0.4])
    assert find_depth_steps(np.concatenate([wall, farther])) is None


@pytest.mark.parametrize(
    "relative",
    ["real/rs1.pcd", "real/cturtle.pcd", "real/dragon1.xyz", "real/bunny_part1.xyz", "bunny/bun000.ply"],
)
def test_real_scans_show_no_coarse_shells(relative):
    found = find_depth_steps(read_points(shared_file(relative)))
    assert found is None or not found.coarse


def test_what_it_does_not_look_at():
    rng = np.random.default_rng(5)
    cloud = quantised(room_corner(rng), 0.06, "z", rng)
    assert find_depth_steps(cloud[:400]) is None  # too few points
    assert find_depth_steps(cloud[:, :2]) is None  # 2-D
    assert find_depth_steps(-cloud) is None  # behind the sensor along every axis; the range...
    assert find_depth_steps(cloud - np.array([0.0, 0.0, 1.5])) is None  # ...and moved off the sensor's origin
    assert find_depth_steps(np.zeros((1000, 3))) is None  # no extent
    found = find_depth_steps(cloud)
    assert found is not None
    with np.errstate(over="raise", divide="raise", invalid="raise"):  # whatever the units
        for unit in (1e-300, 1e150, 1e300):
            scaled = find_depth_steps(cloud * unit)
            assert scaled is not None and scaled.share == pytest.approx(found.share)
            assert scaled.step == pytest.approx(found.step * unit)
