"""The depth-sensor noise model of the benchmarks (frisicp_bench.sensor)."""

from __future__ import annotations

import numpy as np

from frisicp_bench.scenes import SceneCase
from frisicp_bench.sensor import (
    depth_sensor,
    fixed_rings,
    ring_sampled,
    sensed_crop_case,
    sensed_frames_case,
    visible,
)


def _wall(rng: np.random.Generator) -> np.ndarray:
    """A 4 x 3 wall at x = 2..3 (tilted), seen from the origin."""
    u, v = rng.uniform(-2.0, 2.0, 5000), rng.uniform(-1.5, 1.5, 5000)
    return np.stack([2.5 + 0.25 * u, u, v], axis=1)


def test_the_errors_lie_along_the_rays_from_the_camera() -> None:
    rng = np.random.default_rng(0)
    wall = _wall(rng)
    sensed = depth_sensor(wall, np.zeros(3), 0.01, 0.02, rng)
    rays = wall / np.linalg.norm(wall, axis=1, keepdims=True)
    across = np.linalg.norm(np.cross(sensed - wall, rays), axis=1)
    assert across.max() < 1e-12
    assert 0.005 < np.abs(np.linalg.norm(sensed, axis=1) - np.linalg.norm(wall, axis=1)).mean() < 0.03


def test_without_noise_the_depths_lie_on_shells_a_step_apart_at_the_median_range() -> None:
    rng = np.random.default_rng(1)
    wall = _wall(rng)
    ranges = np.linalg.norm(depth_sensor(wall, np.zeros(3), 0.0, 0.05, rng), axis=1)
    shells = np.unique(np.round(ranges, 9))
    assert shells.size < 60  # 5,000 points on a few dozen shells
    median = np.median(np.linalg.norm(wall, axis=1))
    near_median = np.diff(shells)[np.argmin(np.abs(shells[:-1] - median))]
    assert abs(near_median - 0.05) < 0.005
    # The steps grow with the range squared.
    gaps = np.diff(shells)
    assert gaps[-1] / gaps[0] > (shells[-1] / shells[0]) ** 2 * 0.8


def test_two_sensed_frames_carry_their_truth_and_the_data_is_moved_by_it() -> None:
    rng = np.random.default_rng(2)
    scene = np.concatenate([_wall(rng), _wall(rng) * [1.0, 1.0, -1.0] + [0.0, 0.0, 3.5]])
    case = sensed_frames_case(scene, "walls", 0.0, 0.1, 0.0, rng)
    assert case.truth is not None and case.suite == "frames"
    landed = case.truth.apply(case.data)
    # Without noise or steps the data land on the scene (each frame is a subset of it).
    distances = np.min(np.linalg.norm(landed[:200, None, :] - scene[None], axis=2), axis=1)
    assert distances.max() < 1e-9
    assert abs(np.log(case.truth.scale)) <= 0.05 + 1e-12


def test_a_noise_stream_of_its_own_redraws_the_noise_and_keeps_the_frames() -> None:
    # benchmarks/noise_bias.py: the same points, cameras and truth, another noise draw, on the
    # clouds it names.
    scene = np.concatenate(
        [_wall(np.random.default_rng(3)), _wall(np.random.default_rng(4)) * [1.0, 1.0, -1.0]]
    )

    def frames(noise: float, draw: int, noisy: tuple[str, ...] = ("data", "model")) -> SceneCase:
        return sensed_frames_case(
            scene,
            "walls",
            0.0,
            0.1,
            noise,
            np.random.default_rng(5),
            noise_rng=np.random.default_rng(draw),
            noisy=noisy,
        )

    clean, one, other = frames(0.0, 0), frames(0.01, 0), frames(0.01, 1)
    for case in (one, other):
        assert case.truth is not None and clean.truth is not None
        # The same motion; placed about the model's centroid, which the noise moves a little.
        assert case.truth.scale == clean.truth.scale
        assert np.array_equal(case.truth.rotation, clean.truth.rotation)
        assert np.linalg.norm(case.truth.translation - clean.truth.translation) < 0.05
    for case in (one, other):
        assert case.data.shape == clean.data.shape and case.model.shape == clean.model.shape
    moved = [np.linalg.norm(case.model - clean.model, axis=1) for case in (one, other)]
    assert 0.01 < moved[0].mean() < 0.1 and 0.01 < moved[1].mean() < 0.1
    assert not np.allclose(moved[0], moved[1])
    data_only = frames(0.01, 0, ("data",))
    assert np.array_equal(data_only.model, clean.model)
    assert data_only.truth is not None and one.truth is not None
    assert np.allclose(data_only.truth.apply(data_only.data), one.truth.apply(one.data))


def test_each_sensed_cloud_says_where_its_camera_stood_in_its_own_coordinates() -> None:
    # About that point each cloud's depths lie on the camera's shells, as a stream sees a cloud
    # in its sensor's frame (benchmarks/depth_sensor.py, the stream's columns).
    rng = np.random.default_rng(3)
    scene = np.concatenate([_wall(rng), _wall(rng) * [1.0, 1.0, -1.0] + [0.0, 0.0, 3.5]])
    case = sensed_frames_case(scene, "walls", 0.04, 0.1, 0.0, rng)
    crop = sensed_crop_case(scene, "walls", 0.4, 2.0, 0.04, 0.0, rng)
    for cloud, sensor in (
        (case.data, case.sensors[0]),
        (case.model, case.sensors[1]),
        (crop.data, crop.sensors[0]),
    ):
        assert sensor is not None
        ranges = np.linalg.norm(cloud - sensor, axis=1)
        assert np.unique(np.round(1.0 / ranges, 6)).size < 0.02 * ranges.size  # a few dozen shells
    assert crop.sensors[1] is None  # the scene as it is: no one sensor


def test_a_case_in_its_sensors_frames_keeps_its_answer() -> None:
    # Each cloud moved so that its camera stands at the origin (benchmarks/depth_sensor.py
    # --sensor-frames): the truth moves with them, a cloud without a sensor stays.
    rng = np.random.default_rng(5)
    scene = np.concatenate([_wall(rng), _wall(rng) * [1.0, 1.0, -1.0] + [0.0, 0.0, 3.5]])
    for case in (
        sensed_frames_case(scene, "walls", 0.04, 0.1, 0.0, rng),
        sensed_crop_case(scene, "walls", 0.4, 2.0, 0.04, 0.0, rng),
    ):
        moved = case.in_sensor_frames()
        assert case.truth is not None and moved.truth is not None
        assert moved.truth.scale == case.truth.scale
        np.testing.assert_allclose(
            moved.truth.apply(moved.data) + (case.sensors[1] if case.sensors[1] is not None else 0.0),
            case.truth.apply(case.data),
            atol=1e-9,
        )
        assert case.sensors[0] is not None and moved.sensors[0] is not None and not moved.sensors[0].any()
        np.testing.assert_array_equal(moved.data, case.data - case.sensors[0])
        assert (moved.sensors[1] is None) == (case.sensors[1] is None)


def test_a_camera_sees_the_front_wall_and_not_what_it_hides() -> None:
    """A 1 x 1 panel at x = 2 in front of a 4 x 4 wall at x = 4, seen from the origin: the panel
    is all seen; of the wall, the part in the panel's shadow (2 x 2 at x = 4) is hidden but for
    pixels no panel point happened to fall in (random samples, not a sensor's full raster)."""
    rng = np.random.default_rng(4)
    panel = np.column_stack([np.full(4000, 2.0), rng.uniform(-0.5, 0.5, (4000, 2))])
    wall = np.column_stack([np.full(16000, 4.0), rng.uniform(-2.0, 2.0, (16000, 2))])
    seen = visible(np.concatenate([panel, wall]), np.zeros(3))
    assert np.count_nonzero(seen[:, 0] == 2.0) == 4000
    behind = seen[seen[:, 0] == 4.0]

    def inside(points: np.ndarray, half: float) -> int:
        return int(np.count_nonzero(np.all(np.abs(points[:, 1:]) < half, axis=1)))

    assert inside(behind, 0.9) < 0.02 * inside(wall, 0.9)
    outside = np.any(np.abs(behind[:, 1:]) > 1.1, axis=1).sum()
    assert outside > 0.98 * np.any(np.abs(wall[:, 1:]) > 1.1, axis=1).sum()


def test_a_lidar_keeps_thin_rings_evenly_spread_over_the_elevations() -> None:
    """A wall seen by 8 beams: 8 bands of points, each within a tenth of the beams' spacing of
    its elevation, about a fifth of the points in all."""
    rng = np.random.default_rng(5)
    wall = np.column_stack(
        [np.full(20000, 4.0), rng.uniform(-2.0, 2.0, 20000), rng.uniform(-1.0, 1.0, 20000)]
    )
    rings = ring_sampled(wall, np.zeros(3), 8)
    elevation = np.arcsin(rings[:, 2] / np.linalg.norm(rings, axis=1))
    full = np.arcsin(wall[:, 2] / np.linalg.norm(wall, axis=1))
    spacing = np.ptp(full) / 7
    beam = np.round((elevation - full.min()) / spacing)
    assert set(beam.astype(int)) == set(range(8))
    assert np.abs(elevation - (full.min() + beam * spacing)).max() <= 0.1 * spacing + 1e-12
    assert 0.1 < rings.shape[0] / wall.shape[0] < 0.3


def test_a_real_lidars_rings_stand_at_the_same_elevations_wherever_it_stands() -> None:
    """Beams 2 degrees apart: from two places at one height the rings lie on the same cones
    (multiples of the spacing), each within a tenth of it."""
    rng = np.random.default_rng(6)
    wall = np.column_stack(
        [np.full(20000, 4.0), rng.uniform(-2.0, 2.0, 20000), rng.uniform(-1.0, 1.0, 20000)]
    )
    spacing = np.radians(2.0)
    for camera in (np.zeros(3), np.array([0.5, 0.7, 0.0])):
        rings = fixed_rings(wall, camera, spacing)
        offsets = rings - camera
        elevation = np.arcsin(offsets[:, 2] / np.linalg.norm(offsets, axis=1))
        beam = np.round(elevation / spacing)
        assert np.abs(elevation - beam * spacing).max() <= 0.1 * spacing + 1e-12
        assert len(set(beam.astype(int))) >= 12  # about +-14 degrees of wall: 13-15 rings
        assert 0.1 < rings.shape[0] / wall.shape[0] < 0.3


def test_level_frames_move_the_second_sensor_across_the_rings_axis_only() -> None:
    rng = np.random.default_rng(7)
    scene = np.concatenate([_wall(rng), _wall(rng) * [1.0, 1.0, -1.0] + [0.0, 0.0, 3.5]])
    for level in (False, True):
        case = sensed_frames_case(scene, "walls", 0.0, 0.3, 0.0, np.random.default_rng(8), level=level)
        assert case.truth is not None and case.sensors[0] is not None and case.sensors[1] is not None
        offset = case.sensors[1] - case.truth.apply(case.sensors[0][None])[0]
        assert np.linalg.norm(offset) > 0.01
        assert (abs(offset[2]) < 1e-9 * np.linalg.norm(offset)) == level


def test_flying_pixels_lie_between_the_fronts_at_a_depth_edge() -> None:
    """The panel before the wall: the extra points lie half-way (x = 3) on rays through the
    panel's rim, about one per pixel along its outline, none elsewhere."""
    rng = np.random.default_rng(6)
    panel = np.column_stack([np.full(4000, 2.0), rng.uniform(-0.5, 0.5, (4000, 2))])
    wall = np.column_stack([np.full(16000, 4.0), rng.uniform(-2.0, 2.0, (16000, 2))])
    clouds = np.concatenate([panel, wall])
    plain, flown = visible(clouds, np.zeros(3)), visible(clouds, np.zeros(3), flying=True)
    np.testing.assert_array_equal(flown[: plain.shape[0]], plain)
    extra = flown[plain.shape[0] :]
    assert 40 < extra.shape[0] < 400
    np.testing.assert_allclose(extra[:, 0], 3.0, atol=0.05)  # half-way along x between 2 and 4
    rim = np.max(np.abs(extra[:, 1:] / extra[:, :1] * 2.0), axis=1)  # where the ray meets the panel
    assert np.all((rim > 0.4) & (rim < 0.51))


def test_on_shells_the_noise_comes_first_and_every_depth_lies_on_a_shell() -> None:
    rng = np.random.default_rng(7)
    wall = _wall(rng)
    blurred = np.linalg.norm(depth_sensor(wall, np.zeros(3), 0.002, 0.05, np.random.default_rng(1)), axis=1)
    exact = np.linalg.norm(
        depth_sensor(wall, np.zeros(3), 0.002, 0.05, np.random.default_rng(1), True), axis=1
    )
    assert np.unique(np.round(blurred, 9)).size == wall.shape[0]  # noise after the steps: all distinct
    assert np.unique(np.round(exact, 9)).size < 60  # noise before them: the shells only
