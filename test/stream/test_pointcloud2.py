"""PointCloud2 <-> numpy for rclpy and rosbags messages: layouts, byte orders, bad clouds."""

from __future__ import annotations

import numpy as np
import pytest
from support.data import axis_rotation

from frisicp_core import Similarity, downsample
from frisicp_ros.node.message_types import rclpy_message_types
from frisicp_ros.stream.messages import HeaderLike, PointCloud2Like, PointFieldLike, TimeLike
from frisicp_ros.stream.outputs import MessageTypes, rosbags_message_types
from frisicp_ros.stream.pointcloud2 import (
    DATATYPES,
    FLOAT32,
    FLOAT64,
    INT16,
    UINT8,
    CloudError,
    CloudParts,
    FieldSpec,
    aligned_cloud,
    cloud_to_points,
    coordinate_views,
    points_to_parts,
    read_cloud,
)

FLAVOURS = {"rclpy": rclpy_message_types, "rosbags": rosbags_message_types}


@pytest.fixture(params=sorted(FLAVOURS), scope="module")
def types(request) -> MessageTypes:
    return FLAVOURS[request.param]()


def make(types: MessageTypes, parts: CloudParts, frame: str = "lidar", **overrides) -> object:
    """A real message of the flavour; ``overrides`` replace CloudParts fields (to break them)."""
    values = {name: getattr(parts, name) for name in CloudParts.__dataclass_fields__}
    values.update(overrides)
    return types.point_cloud(CloudParts(**values), types.header(1_500_000_000, frame))


def grid_points(n: int = 40) -> np.ndarray:
    rng = np.random.default_rng(1)
    return np.round(rng.uniform(-50, 50, size=(n, 3)))  # integers: exact in every datatype


def members(protocol: type) -> set[str]:
    """The attributes a message protocol of frisicp_ros.stream.messages names (its own and inherited)."""
    return {
        name
        for cls in protocol.__mro__
        if cls.__module__ == "frisicp_ros.stream.messages"
        for name, member in vars(cls).items()
        if isinstance(member, property)
    }


def test_real_messages_have_every_attribute_the_stream_protocols_name(types):
    """mypy checks the stream against the protocols; this checks the protocols against rclpy and rosbags."""
    cloud = make(types, points_to_parts(grid_points()))
    assert members(PointCloud2Like) == {
        *("header", "height", "width", "fields", "is_bigendian", "point_step", "row_step", "data", "is_dense")
    }
    for protocol, message in (
        (PointCloud2Like, cloud),
        (HeaderLike, cloud.header),
        (TimeLike, cloud.header.stamp),
        (PointFieldLike, cloud.fields[0]),
    ):
        assert {name for name in members(protocol) if not hasattr(message, name)} == set(), protocol.__name__


@pytest.mark.parametrize("datatype", sorted(DATATYPES))
@pytest.mark.parametrize("big_endian", [False, True])
def test_every_datatype_and_byte_order_round_trips(types, datatype, big_endian):
    points = grid_points()
    if DATATYPES[datatype].kind == "u":
        points = np.abs(points)
    if DATATYPES[datatype].itemsize == 1:
        points = np.clip(points, -100, 100)
    parts = points_to_parts(
        points,
        {"intensity": np.arange(len(points), dtype=np.float32)},
        datatype=datatype,
        big_endian=big_endian,
    )
    msg = make(types, parts)
    np.testing.assert_array_equal(cloud_to_points(msg), points)
    np.testing.assert_array_equal(cloud_to_points(msg, dims=2), points[:, :2])


def test_padding_offsets_and_organized_rows_with_row_padding(types):
    # 2 x 3 organized cloud, fields out of order with gaps, 4 padding bytes at the end of each row.
    height, width, point_step, row_pad = 2, 3, 32, 4
    row_step = width * point_step + row_pad
    points = grid_points(height * width)
    data = np.zeros(height * row_step, dtype=np.uint8)
    fields = (
        FieldSpec("intensity", 0, UINT8),
        FieldSpec("z", 4, FLOAT64),
        FieldSpec("x", 16, FLOAT32),
        FieldSpec("y", 24, INT16),
    )
    for index, (x, y, z) in enumerate(points):
        row, col = divmod(index, width)
        base = row * row_step + col * point_step
        data[base] = index
        data[base + 4 : base + 12] = np.frombuffer(np.float64(z).tobytes(), np.uint8)
        data[base + 16 : base + 20] = np.frombuffer(np.float32(x).tobytes(), np.uint8)
        data[base + 24 : base + 26] = np.frombuffer(np.int16(y).tobytes(), np.uint8)
    parts = CloudParts(height, width, fields, False, point_step, row_step, data, True)
    msg = make(types, parts)
    np.testing.assert_array_equal(cloud_to_points(msg), points)


def test_views_are_zero_copy(types):
    msg = make(types, points_to_parts(grid_points()))
    views = coordinate_views(msg)
    assert all(np.shares_memory(view, np.frombuffer(msg.data, np.uint8)) for view in views)


def test_nan_and_inf_points_are_dropped_and_cap_downsamples(types):
    points = grid_points(100)
    points[3, 0] = np.nan
    points[7, 2] = np.inf
    msg = make(types, points_to_parts(points))
    converted = cloud_to_points(msg)
    assert converted.shape == (98, 3) and np.isfinite(converted).all()
    capped = cloud_to_points(msg, max_points=30, seed=4)
    assert capped.shape == (30, 3)
    np.testing.assert_array_equal(capped, cloud_to_points(msg, max_points=30, seed=4))  # reproducible
    assert {tuple(p) for p in capped} <= {tuple(p) for p in converted}


def test_cap_is_drawn_before_conversion_as_downsample_would_draw_it(types):
    points = grid_points(5000) + np.random.default_rng(3).uniform(size=(5000, 3))
    points[::11, 1] = np.nan
    msg = make(types, points_to_parts(points, datatype=FLOAT64))
    finite = points[np.isfinite(points).all(axis=1)]
    read = read_cloud(msg, max_points=700, seed=9)
    np.testing.assert_array_equal(read.points, downsample(finite, 700, np.random.default_rng(9)))
    assert read.points.flags.c_contiguous and read.points.dtype == np.float64
    assert (read.finite, read.voxels) == (len(finite), len(finite))


@pytest.mark.parametrize(
    ("break_it", "message"),
    [
        (lambda parts: {"data": parts.data[:-1]}, r"len\(data\)"),
        (lambda parts: {"fields": parts.fields[1:]}, "no 'x' field"),
        (
            lambda parts: {
                "fields": (FieldSpec("x", 0, FLOAT32), FieldSpec("y", 2, FLOAT32), FieldSpec("z", 8, FLOAT32))
            },
            "overlap",
        ),
        (
            lambda parts: {
                "point_step": 8,
                "row_step": 8 * parts.width,
                "data": parts.data[: 8 * parts.width],
            },
            "point_step too small",
        ),
        (lambda parts: {"fields": (FieldSpec("x", 0, 9), *parts.fields[1:])}, "unknown datatype"),
        (
            lambda parts: {
                "fields": (*parts.fields, FieldSpec("x", 12, FLOAT32)),
                "point_step": 16,
                "row_step": 16 * parts.width,
                "data": np.zeros(16 * parts.width, np.uint8),
            },
            "appears twice",
        ),
        (lambda parts: {"row_step": 4, "data": parts.data[: 4 * parts.height]}, "row_step"),
        (lambda parts: {"width": 0, "row_step": 0, "data": parts.data[:0]}, "empty cloud"),
        (
            lambda parts: {
                "data": np.frombuffer(np.full(3 * parts.width, np.nan, np.float32).tobytes(), np.uint8)
            },
            "no finite points",
        ),
    ],
)
def test_bad_clouds_raise_cloud_error(types, break_it, message):
    parts = points_to_parts(grid_points(10))
    msg = make(types, parts, **break_it(parts))
    with pytest.raises(CloudError, match=message):
        cloud_to_points(msg)
    assert issubclass(CloudError, ValueError)


@pytest.mark.parametrize("dims", [2, 3])
def test_aligned_cloud_maps_coordinates_and_keeps_other_fields(types, dims):
    points = grid_points(50) / 10.0
    points[5] = np.nan
    intensity = np.linspace(0, 1, 50, dtype=np.float32)
    rgb = np.arange(50, dtype=np.uint32) * 1000
    msg = make(types, points_to_parts(points, {"intensity": intensity, "rgb": rgb}, datatype=FLOAT64))
    rotation = axis_rotation(3, 30.0)[:dims, :dims] if dims == 3 else axis_rotation(2, 30.0)
    similarity = Similarity(1.7, rotation, np.arange(dims) + 0.5)
    out = aligned_cloud(msg, similarity, dims, lambda parts: types.point_cloud(parts, msg.header))
    assert isinstance(out, type(msg))
    table = np.frombuffer(out.data, np.uint8).view(
        np.dtype(
            {
                "names": ["x", "y", "z", "intensity", "rgb"],
                "formats": ["<f8", "<f8", "<f8", "<f4", "<u4"],
                "offsets": [f.offset for f in out.fields],
                "itemsize": out.point_step,
            }
        )
    )
    expected = points.copy()
    expected[:, :dims] = similarity.apply(points[:, :dims])
    mapped = np.column_stack([table["x"], table["y"], table["z"]])
    np.testing.assert_allclose(mapped, expected, atol=1e-12)  # NaN row stays NaN, 2-D keeps z
    np.testing.assert_array_equal(table["intensity"], intensity)
    np.testing.assert_array_equal(table["rgb"], rgb)
    np.testing.assert_array_equal(cloud_to_points(msg)[:2], np.delete(points, 5, 0)[:2])  # input untouched
