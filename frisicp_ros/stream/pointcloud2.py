"""sensor_msgs/PointCloud2 <-> (N, m) float64 points, for rclpy and rosbags messages alike.

Messages are duck-typed (``frisicp_ros.stream.messages``): anything with ``height width fields
is_bigendian point_step row_step data`` (and ``header`` for the caller) works, where ``fields``
items have ``name offset datatype count``. rclpy stores ``data`` as ``array.array('B')``, rosbags as a uint8 ``np.ndarray``; both
expose the buffer protocol, so every field is read through a strided numpy view of the original
bytes (no copy) and only the selected coordinates are copied, once, into float64.

No rclpy import here: the offline bag mode uses this module without ROS.
"""

from __future__ import annotations

import itertools
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from enum import Enum
from typing import Any, Literal, TypeVar

import numpy as np

from frisicp_core import Similarity, downsample, voxel_centroids, voxel_filter
from frisicp_ros.stream.messages import CloudLayoutLike, PointCloud2Like, PointFieldLike

# sensor_msgs/PointField datatype constants (identical in rclpy and rosbags).
INT8, UINT8, INT16, UINT16, INT32, UINT32, FLOAT32, FLOAT64 = range(1, 9)
DATATYPES: dict[int, np.dtype] = {
    INT8: np.dtype(np.int8),
    UINT8: np.dtype(np.uint8),
    INT16: np.dtype(np.int16),
    UINT16: np.dtype(np.uint16),
    INT32: np.dtype(np.int32),
    UINT32: np.dtype(np.uint32),
    FLOAT32: np.dtype(np.float32),
    FLOAT64: np.dtype(np.float64),
}
COORDINATE_NAMES = ("x", "y", "z")


class CloudError(ValueError):
    """A PointCloud2 that cannot be registered: malformed, empty, or without finite points."""


@dataclass(frozen=True)
class FieldSpec:
    """One PointField as plain values (what ``make_cloud`` callbacks turn into messages)."""

    name: str
    offset: int
    datatype: int
    count: int = 1


@dataclass(frozen=True)
class CloudParts:
    """Every PointCloud2 field except the header, with ``data`` as a uint8 numpy array."""

    height: int
    width: int
    fields: tuple[FieldSpec, ...]
    is_bigendian: bool
    point_step: int
    row_step: int
    data: np.ndarray
    is_dense: bool


CloudT = TypeVar("CloudT")


def check_dims(dims: int) -> None:
    if dims not in (2, 3):
        raise ValueError(f"dims must be 2 (x y) or 3 (x y z), got {dims}")


def coordinate_views(msg: CloudLayoutLike, dims: int = 3) -> list[np.ndarray]:
    """Zero-copy (height, width) views of the x, y(, z) fields, in the message's byte order.

    Raises CloudError for a malformed layout; the views keep ``msg.data`` alive.
    """
    check_dims(dims)
    height, width = int(msg.height), int(msg.width)
    point_step, row_step = int(msg.point_step), int(msg.row_step)
    buffer = np.frombuffer(msg.data, dtype=np.uint8)
    if buffer.size != row_step * height:
        raise CloudError(
            f"malformed cloud: len(data) = {buffer.size} but row_step * height = {row_step} * {height}"
            f" = {row_step * height}"
        )
    if point_step <= 0:
        raise CloudError(f"malformed cloud: point_step must be positive, got {point_step}")
    if row_step < width * point_step:
        raise CloudError(
            f"malformed cloud: row_step {row_step} < width * point_step = {width} * {point_step}"
        )
    fields = _validated_fields(msg.fields, point_step)
    byte_order: Literal[">", "<"] = ">" if msg.is_bigendian else "<"
    views = []
    for name in COORDINATE_NAMES[:dims]:
        if name not in fields:
            raise CloudError(f"malformed cloud: no '{name}' field (fields: {', '.join(fields) or 'none'})")
        field = fields[name]
        dtype = DATATYPES[field.datatype].newbyteorder(byte_order)
        if height * width == 0:  # numpy refuses strided views of an empty buffer
            views.append(np.empty((height, width), dtype=dtype))
            continue
        views.append(
            np.ndarray(
                shape=(height, width),
                dtype=dtype,
                buffer=buffer,
                offset=field.offset,
                strides=(row_step, point_step),
            )
        )
    return views


def _validated_fields(fields: Sequence[PointFieldLike], point_step: int) -> dict[str, PointFieldLike]:
    """Fields by name, after checking datatypes, bounds and that no two fields share bytes."""
    by_name: dict[str, PointFieldLike] = {}
    extents: list[tuple[int, int, str]] = []
    for field in fields:
        if field.datatype not in DATATYPES:
            raise CloudError(f"malformed cloud: field '{field.name}' has unknown datatype {field.datatype}")
        if field.name in by_name:
            raise CloudError(f"malformed cloud: field '{field.name}' appears twice")
        count = max(int(field.count), 1)  # count 0 appears in the wild and means 1
        end = int(field.offset) + DATATYPES[field.datatype].itemsize * count
        if field.offset < 0 or end > point_step:
            raise CloudError(
                f"malformed cloud: field '{field.name}' spans bytes {field.offset}..{end} but point_step"
                f" is {point_step} (point_step too small)"
            )
        extents.append((int(field.offset), end, field.name))
        by_name[field.name] = field
    extents.sort()
    for (_, end_a, name_a), (start_b, _, name_b) in itertools.pairwise(extents):
        if start_b < end_a:
            raise CloudError(f"malformed cloud: fields '{name_a}' and '{name_b}' overlap")
    return by_name


class VoxelMode(str, Enum):
    """What the voxel grid keeps of each occupied voxel; the values are the ``voxel_mode``
    parameter's (``frisicp_core.voxel``)."""

    FIRST = "first"  # its first point: a measured point (frisicp_core.voxel_filter)
    CENTROID = "centroid"  # the mean of its points: smooths quantised depth (voxel_centroids)


VOXEL_MODES: tuple[str, ...] = tuple(mode.value for mode in VoxelMode)


@dataclass(frozen=True)
class CloudPoints:
    """What :func:`read_cloud` made of a message: the points and what it cost.

    ``finite``: finite points in the message; ``voxels``: points left by the voxel grid (=
    ``finite`` without one); ``points``: after the ``max_points`` cap. ``convert_seconds``:
    reading the coordinate fields into float64 (only the points kept when there is no voxel
    grid); ``downsample_seconds``: the voxel grid and the random cap.
    """

    points: np.ndarray
    finite: int
    voxels: int
    convert_seconds: float
    downsample_seconds: float


def cloud_to_points(
    msg: CloudLayoutLike,
    dims: int = 3,
    max_points: int | None = None,
    seed: int = 0,
    voxel_size: float = 0.0,
    voxel_mode: str = VoxelMode.FIRST.value,
) -> np.ndarray:
    """The finite points of a PointCloud2 as a C-contiguous (N, dims) float64 array.

    Organized clouds are flattened row by row; points with a NaN/Inf coordinate are dropped.
    With ``voxel_size`` > 0 one point per occupied voxel is kept (``frisicp_core.voxel``): its
    first point, or with ``voxel_mode`` "centroid" the mean of its points. Above ``max_points``
    (None or 0: no cap) a uniformly random subset in the original order is kept, reproducible
    from ``seed``. Raises CloudError for malformed, empty and all-NaN clouds.
    """
    return read_cloud(msg, dims, max_points, seed, voxel_size, voxel_mode).points


def read_cloud(
    msg: CloudLayoutLike,
    dims: int = 3,
    max_points: int | None = None,
    seed: int = 0,
    voxel_size: float = 0.0,
    voxel_mode: str = VoxelMode.FIRST.value,
) -> CloudPoints:
    """:func:`cloud_to_points` with its counts and timings.

    Without a voxel grid the cap is drawn before anything is converted: only the finite mask is
    computed over the whole cloud (on the zero-copy field views), and only the kept points are
    copied into float64. The subset is the one ``frisicp_core.downsample`` draws from the finite
    points with ``default_rng(seed)``, so the result does not depend on the order of the steps.
    """
    if voxel_mode not in VOXEL_MODES:
        raise ValueError(f"voxel_mode must be one of {', '.join(VOXEL_MODES)}, got {voxel_mode!r}")
    started = time.perf_counter()
    views = coordinate_views(msg, dims)
    total = int(msg.height) * int(msg.width)
    if total == 0:
        raise CloudError("empty cloud: width * height = 0")
    columns = [view.reshape(-1) for view in views]  # views, unless rows are padded
    finite_index = _finite_index(columns)
    finite = total if finite_index is None else finite_index.size
    if finite == 0:
        raise CloudError(f"cloud has no finite points: all {total} points contain NaN/Inf")
    rng = np.random.default_rng(seed)
    if voxel_size > 0:
        points = _gather(columns, finite_index)
        converted = time.perf_counter()
        grid = voxel_centroids if voxel_mode == VoxelMode.CENTROID.value else voxel_filter
        points = grid(points, voxel_size)
        voxels = points.shape[0]
        if max_points:
            points = downsample(points, int(max_points), rng)
        return CloudPoints(
            np.ascontiguousarray(points), finite, voxels, converted - started, time.perf_counter() - converted
        )
    chosen = finite_index
    sampling = 0.0
    if max_points and finite > max_points:
        drawn = time.perf_counter()
        # downsample()'s subset, np.sort(rng.choice(...)), without the sort: mark, then list in order
        marked = np.zeros(finite, dtype=bool)
        marked[rng.choice(finite, size=int(max_points), replace=False)] = True
        chosen = np.flatnonzero(marked) if finite_index is None else finite_index[marked]
        sampling = time.perf_counter() - drawn
    points = _gather(columns, chosen)
    return CloudPoints(points, finite, finite, time.perf_counter() - started - sampling, sampling)


def _finite_index(columns: Sequence[np.ndarray]) -> np.ndarray | None:
    """Indices of the points whose coordinates are all finite; None when every point is."""
    mask: np.ndarray | None = None
    for column in columns:
        if column.dtype.kind != "f":
            continue  # integer coordinates are always finite
        with np.errstate(invalid="ignore"):  # signalling NaNs (garbage bytes) are not finite
            column_finite = np.isfinite(column)
        mask = column_finite if mask is None else np.logical_and(mask, column_finite, out=mask)
    if mask is None or mask.all():
        return None
    return np.flatnonzero(mask)


def _gather(columns: Sequence[np.ndarray], index: np.ndarray | None) -> np.ndarray:
    """The rows ``index`` (None: all) of the coordinate columns as a C-contiguous float64 array."""
    count = columns[0].shape[0] if index is None else index.shape[0]
    points = np.empty((count, len(columns)), dtype=np.float64)
    # Garbage bytes (a wrong byte order flag) hold signalling NaNs: dropped already, not warned about.
    with np.errstate(invalid="ignore"):
        for k, column in enumerate(columns):
            points[:, k] = column if index is None else column[index]  # the one copy into float64
    return points


def aligned_cloud(
    msg: PointCloud2Like, similarity: Similarity, dims: int, make_cloud: Callable[[CloudParts], CloudT]
) -> CloudT:
    """``msg`` with x, y(, z) mapped through ``similarity``; every other byte kept.

    A copy of the original data buffer is rewritten in place, so intensity, rgb, ring, time,
    padding and the organized layout all survive. NaN points stay NaN. In 2-D mode z (if any) is
    left as it was. Integer coordinate fields are rounded and clipped to their range.
    ``make_cloud`` turns the resulting :class:`CloudParts` into a message of the caller's
    flavour (rclpy or rosbags) and adds the header.
    """
    if similarity.dim != dims:
        raise ValueError(f"a {similarity.dim}-D similarity cannot map {dims}-D points")
    data = np.frombuffer(msg.data, dtype=np.uint8).copy()
    copy = _CloudOverData(msg, data)
    source = coordinate_views(msg, dims)
    target = coordinate_views(copy, dims)
    points = np.column_stack([view.reshape(-1).astype(np.float64) for view in source])
    mapped = similarity.apply(points)
    for column, view in enumerate(target):
        values = mapped[:, column].reshape(view.shape)
        if view.dtype.kind in "iu":
            info = np.iinfo(view.dtype)
            values = np.clip(np.rint(np.nan_to_num(values)), info.min, info.max)
        view[...] = values
    return make_cloud(CloudParts(data=data, **layout_of(msg)))


class _CloudOverData:
    """The layout of ``msg`` over another buffer, so coordinate_views can write into a copy."""

    def __init__(self, msg: CloudLayoutLike, data: np.ndarray) -> None:
        self.height, self.width, self.fields = msg.height, msg.width, msg.fields
        self.is_bigendian, self.point_step, self.row_step = msg.is_bigendian, msg.point_step, msg.row_step
        self.data = data


def layout_of(msg: PointCloud2Like) -> dict[str, Any]:
    """Every CloudParts field of a PointCloud2 message but ``data``, as plain values."""
    return {
        "height": int(msg.height),
        "width": int(msg.width),
        "fields": field_specs(msg.fields),
        "is_bigendian": bool(msg.is_bigendian),
        "point_step": int(msg.point_step),
        "row_step": int(msg.row_step),
        "is_dense": bool(msg.is_dense),
    }


def field_specs(fields: Sequence[PointFieldLike]) -> tuple[FieldSpec, ...]:
    return tuple(FieldSpec(str(f.name), int(f.offset), int(f.datatype), int(f.count)) for f in fields)


def points_to_parts(
    points: np.ndarray,
    extra: dict[str, np.ndarray] | None = None,
    datatype: int = FLOAT32,
    big_endian: bool = False,
) -> CloudParts:
    """An unorganized cloud of x, y(, z) in ``datatype`` plus ``extra`` per-point fields.

    ``extra`` maps a field name to an (N,) array; its dtype picks the PointField datatype.
    Used by the demo, the tests and the benchmarks to publish clouds.
    """
    pts = np.asarray(points, dtype=np.float64)
    if pts.ndim != 2 or pts.shape[1] not in (2, 3):
        raise ValueError(f"points must be (N, 2) or (N, 3), got {pts.shape}")
    byte_order: Literal[">", "<"] = ">" if big_endian else "<"
    columns: list[tuple[str, np.dtype, np.ndarray]] = [
        (name, DATATYPES[datatype], pts[:, i]) for i, name in enumerate(COORDINATE_NAMES[: pts.shape[1]])
    ]
    codes = {dtype: code for code, dtype in DATATYPES.items()}
    for name, values in (extra or {}).items():
        values = np.asarray(values)
        if values.dtype not in codes:
            raise ValueError(f"field '{name}': dtype {values.dtype} has no PointField datatype")
        columns.append((name, values.dtype, values))
    record = np.dtype([(name, dtype.newbyteorder(byte_order)) for name, dtype, _ in columns])
    table = np.empty(pts.shape[0], dtype=record)
    for name, _, values in columns:
        table[name] = values
    offsets = {name: offset for name, (_, offset, *_) in (record.fields or {}).items()}
    fields = tuple(FieldSpec(name, offsets[name], codes[dtype]) for name, dtype, _ in columns)
    return CloudParts(
        height=1,
        width=pts.shape[0],
        fields=fields,
        is_bigendian=big_endian,
        point_step=record.itemsize,
        row_step=record.itemsize * pts.shape[0],
        data=table.view(np.uint8),
        is_dense=bool(np.isfinite(pts).all()),
    )
