"""Test bags of PointCloud2 clouds made from known similarities of a shape.

Three independent writers: rosbags' rosbag2 writer (sqlite3 and mcap storage), rosbags' ROS 1
writer, and the ``mcap`` + ``mcap-ros2-support`` packages (Foxglove's, sharing no code with
rosbags). The clouds are encoded here by hand with numpy, not with frisicp_ros.stream.pointcloud2, so a
bug in the conversion under test cannot cancel itself out.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from frisicp_core import Similarity, axis_angle_rotation, bumpy_surface

MODEL_TOPIC = "/map_cloud"
DATA_TOPIC = "/scan_cloud"
OTHER_TOPIC = "/chatter"  # a non-cloud topic, for wrong-type errors
MODEL_FRAME = "map"
DATA_FRAME = "lidar"

# x, y, z, intensity as float32: what most lidar drivers publish.
FIELDS = (("x", 0), ("y", 4), ("z", 8), ("intensity", 12))
POINT_STEP = 16
FLOAT32 = 7  # sensor_msgs/PointField.FLOAT32


@dataclass(frozen=True)
class CloudRecord:
    topic: str
    bag_ns: int  # the bag's receive time stamp
    header_ns: int  # header.stamp
    frame_id: str
    points: np.ndarray  # (N, 3)


@dataclass
class Scenario:
    """Records in bag order; ``truth[data bag_ns]`` maps that data cloud onto the model it came from."""

    records: list[CloudRecord] = field(default_factory=list)
    truth: dict[int, Similarity] = field(default_factory=dict)
    source_model_ns: dict[int, int] = field(default_factory=dict)  # data bag_ns -> model bag_ns

    def data_records(self) -> list[CloudRecord]:
        return [r for r in self.records if r.topic == DATA_TOPIC]


def truth_for(k: int) -> Similarity:
    """A different, well-separated similarity for every data cloud."""
    rotation = axis_angle_rotation([0.3, 1.0, 0.2 + 0.1 * k], np.deg2rad(10.0 + 7.0 * k))
    return Similarity(0.5 + 0.6 * k, rotation, [0.4 * k - 1.0, 2.0, 0.3 * k])


def data_cloud(model: np.ndarray, truth: Similarity, seed: int) -> np.ndarray:
    """80 % of the model's points, shuffled, moved by truth^-1: model ≈ truth(data)."""
    rng = np.random.default_rng(seed)
    keep = rng.permutation(len(model))[: int(0.8 * len(model))]
    return truth.inverse().apply(model[keep])


def standard_scenario(points: int = 1500) -> Scenario:
    """Models at header times 1, 2, 3 s; a data cloud with the same stamp 5 ms after each
    (recorded later, as a sensor pipeline would), plus one at 2.5 s with no model of its stamp.

    latest_model pairs all four data clouds (the 2.5 s one with the 2 s model);
    synchronized (tolerance < 0.5 s) pairs only the three with a matching model stamp.
    """
    sec = 1_000_000_000
    scenario = Scenario()
    models: dict[int, np.ndarray] = {}
    plan = [
        ("model", 1 * sec),
        ("data", 1 * sec),
        ("model", 2 * sec),
        ("data", 2 * sec),
        ("data", 2 * sec + sec // 2),
        ("model", 3 * sec),
        ("data", 3 * sec),
    ]
    last_model_ns = 0
    for k, (kind, stamp) in enumerate(plan):
        if kind == "model":
            models[stamp] = bumpy_surface(points, seed=stamp // sec)
            last_model_ns = stamp
            scenario.records.append(CloudRecord(MODEL_TOPIC, stamp, stamp, MODEL_FRAME, models[stamp]))
            continue
        truth = truth_for(len(scenario.truth))
        bag_ns = stamp + 5_000_000
        scenario.records.append(
            CloudRecord(DATA_TOPIC, bag_ns, stamp, DATA_FRAME, data_cloud(models[last_model_ns], truth, k))
        )
        scenario.truth[bag_ns] = truth
        scenario.source_model_ns[bag_ns] = last_model_ns
    return scenario


def one_model_then_data(pairs: int, points: int) -> tuple[list[CloudRecord], dict[int, Similarity]]:
    """One model at 1 s, then ``pairs`` data clouds 0.1 s apart of known poses (four, in turn):
    the records, and the truth by data bag time."""
    model = bumpy_surface(points, seed=1)
    records = [CloudRecord(MODEL_TOPIC, 10**9, 10**9, MODEL_FRAME, model)]
    truth = {}
    for k in range(pairs):
        stamp = 2 * 10**9 + k * 10**8
        truth[stamp] = truth_for(k % 4)
        records.append(CloudRecord(DATA_TOPIC, stamp, stamp, DATA_FRAME, data_cloud(model, truth[stamp], k)))
    return records, truth


def cloud_bytes(points: np.ndarray) -> bytes:
    packed = np.zeros(
        len(points),
        dtype=np.dtype(
            {
                "names": [name for name, _ in FIELDS],
                "formats": ["<f4"] * len(FIELDS),
                "offsets": [offset for _, offset in FIELDS],
                "itemsize": POINT_STEP,
            }
        ),
    )
    packed["x"], packed["y"], packed["z"] = points[:, 0], points[:, 1], points[:, 2]
    packed["intensity"] = np.arange(len(points)) % 100
    return packed.tobytes()


def assert_matches_truth(record: dict, truth: Similarity) -> None:
    """A bag-mode JSON line is a usable pose (ok, converged, reliable) equal to ``truth``."""
    import pytest

    from frisicp_core import rotation_angle

    estimate = Similarity.from_quaternion(record["scale"], record["quaternion_xyzw"], record["translation"])
    assert record["ok"] and record["converged"] and record["reliable"] and record["reason"] == ""
    assert estimate.scale == pytest.approx(truth.scale, rel=5e-3)
    assert np.degrees(rotation_angle(estimate.rotation.T @ truth.rotation)) < 0.5
    np.testing.assert_allclose(estimate.translation, truth.translation, atol=0.01 * truth.scale + 0.005)
    np.testing.assert_allclose(np.array(record["rotation"]), estimate.rotation, atol=1e-6)


# --- rosbags writers -------------------------------------------------------------------------


def rosbags_cloud(typestore, record: CloudRecord, ros1: bool = False):
    types = typestore.types  # rosbags spells ROS 1 types with "/msg/" too
    time_type = types["builtin_interfaces/msg/Time"]
    field_type = types["sensor_msgs/msg/PointField"]
    header_type = types["std_msgs/msg/Header"]
    stamp = time_type(sec=record.header_ns // 10**9, nanosec=record.header_ns % 10**9)
    header = (
        header_type(seq=0, stamp=stamp, frame_id=record.frame_id)
        if ros1
        else header_type(stamp=stamp, frame_id=record.frame_id)
    )
    data = np.frombuffer(cloud_bytes(record.points), dtype=np.uint8)
    return types["sensor_msgs/msg/PointCloud2"](
        header=header,
        height=1,
        width=len(record.points),
        fields=[field_type(name=n, offset=o, datatype=FLOAT32, count=1) for n, o in FIELDS],
        is_bigendian=False,
        point_step=POINT_STEP,
        row_step=POINT_STEP * len(record.points),
        data=data,
        is_dense=True,
    )


def write_rosbag2(
    path: Path, records: Sequence[CloudRecord], storage: str = "sqlite3", extra_string_topic: bool = False
) -> Path:
    """A rosbag2 folder at ``path`` (storage "sqlite3" or "mcap") written by rosbags."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    typestore = get_typestore(Stores.ROS2_JAZZY)
    plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
    with Writer(path, version=9, storage_plugin=plugin) as writer:
        connections = {}
        for record in records:
            if record.topic not in connections:
                connections[record.topic] = writer.add_connection(
                    record.topic, "sensor_msgs/msg/PointCloud2", typestore=typestore
                )
            raw = typestore.serialize_cdr(rosbags_cloud(typestore, record), "sensor_msgs/msg/PointCloud2")
            writer.write(connections[record.topic], record.bag_ns, raw)
        if extra_string_topic:
            string_type = typestore.types["std_msgs/msg/String"]
            conn = writer.add_connection(OTHER_TOPIC, "std_msgs/msg/String", typestore=typestore)
            writer.write(
                conn,
                records[0].bag_ns,
                typestore.serialize_cdr(string_type(data="hi"), "std_msgs/msg/String"),
            )
    return path


def write_ros1_bag(path: Path, records: Sequence[CloudRecord]) -> Path:
    """A ROS 1 .bag file written by rosbags."""
    from rosbags.rosbag1 import Writer
    from rosbags.typesys import Stores, get_typestore

    typestore = get_typestore(Stores.ROS1_NOETIC)
    with Writer(path) as writer:
        connections = {}
        for record in records:
            if record.topic not in connections:
                connections[record.topic] = writer.add_connection(
                    record.topic, "sensor_msgs/msg/PointCloud2", typestore=typestore
                )
            msg = rosbags_cloud(typestore, record, ros1=True)
            writer.write(
                connections[record.topic],
                record.bag_ns,
                typestore.serialize_ros1(msg, "sensor_msgs/msg/PointCloud2"),
            )
    return path


# --- the independent writer: mcap + mcap-ros2-support -----------------------------------------

# The schema text a ROS 2 recorder embeds, written out by hand (rosbags is not asked).
POINTCLOUD2_MSGDEF = """\
std_msgs/Header header
uint32 height
uint32 width
PointField[] fields
bool is_bigendian
uint32 point_step
uint32 row_step
uint8[] data
bool is_dense
================================================================================
MSG: std_msgs/Header
builtin_interfaces/Time stamp
string frame_id
================================================================================
MSG: builtin_interfaces/Time
int32 sec
uint32 nanosec
================================================================================
MSG: sensor_msgs/PointField
uint8 INT8    = 1
uint8 UINT8   = 2
uint8 INT16   = 3
uint8 UINT16  = 4
uint8 INT32   = 5
uint8 UINT32  = 6
uint8 FLOAT32 = 7
uint8 FLOAT64 = 8
string name
uint32 offset
uint8  datatype
uint32 count
"""


def write_mcap_ros2(path: Path, records: Sequence[CloudRecord], chunk_size: int = 1024 * 1024) -> Path:
    """A bare ``.mcap`` file written by Foxglove's mcap-ros2-support (no metadata.yaml)."""
    from mcap_ros2.writer import Writer

    with path.open("wb") as stream:
        writer = Writer(stream, chunk_size=chunk_size)
        schema = writer.register_msgdef("sensor_msgs/msg/PointCloud2", POINTCLOUD2_MSGDEF)
        for record in records:
            message = {
                "header": {
                    "stamp": {"sec": record.header_ns // 10**9, "nanosec": record.header_ns % 10**9},
                    "frame_id": record.frame_id,
                },
                "height": 1,
                "width": len(record.points),
                "fields": [{"name": n, "offset": o, "datatype": FLOAT32, "count": 1} for n, o in FIELDS],
                "is_bigendian": False,
                "point_step": POINT_STEP,
                "row_step": POINT_STEP * len(record.points),
                "data": cloud_bytes(record.points),
                "is_dense": True,
            }
            writer.write_message(
                record.topic, schema, message, log_time=record.bag_ns, publish_time=record.bag_ns
            )
        writer.finish()
    return path


def write_mcap_unchunked(path: Path, records: Sequence[CloudRecord]) -> Path:
    """A bare ``.mcap`` with its messages outside chunks, under a CRC of the whole data section
    (mcap's own writer, CDR from rosbags): what only the data section's CRC protects."""
    from mcap.writer import Writer
    from rosbags.typesys import Stores, get_typestore

    typestore = get_typestore(Stores.ROS2_JAZZY)
    with path.open("wb") as stream:
        writer = Writer(stream, use_chunking=False, enable_crcs=True, enable_data_crcs=True)
        writer.start(profile="ros2", library="frisicp tests")
        schema = writer.register_schema("sensor_msgs/msg/PointCloud2", "ros2msg", POINTCLOUD2_MSGDEF.encode())
        channels = {}
        for record in records:
            if record.topic not in channels:
                channels[record.topic] = writer.register_channel(record.topic, "cdr", schema)
            raw = typestore.serialize_cdr(rosbags_cloud(typestore, record), "sensor_msgs/msg/PointCloud2")
            writer.add_message(channels[record.topic], record.bag_ns, bytes(raw), record.bag_ns)
        writer.finish()
    return path
