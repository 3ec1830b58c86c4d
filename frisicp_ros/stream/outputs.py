"""The outputs of a registered pair: messages for rclpy (the node) or rosbags (the result bag),
and the JSON-ready summary of a result (``frisicp register --json``, the bag mode's JSONL).

Both flavours are built by the same code from a :class:`MessageTypes` namespace: every message
is constructed with all its fields as keywords, which rclpy classes accept and rosbags
dataclasses require. The only per-flavour difference is the array type of ``data`` fields:
rclpy wants ``array.array`` (anything else goes through a slow per-element setter, see
docs/node.md), rosbags wants a numpy array.

Topics are relative to the node (``~/transform`` etc.); ``OUTPUT_TOPICS`` lists suffix -> type.

- ``transform`` TransformStamped: rotation and translation of the similarity (the scale is not
  representable there), header.frame_id = model frame, child_frame_id = data frame. 2-D results
  become a rotation about z with z = 0.
- ``pose`` PoseWithCovarianceStamped: the same (R, t) with the 6x6 covariance of the result's
  uncertainty (``Uncertainty.pose_covariance``: x y z roll pitch yaw, row-major); no estimate:
  all zero but ``covariance[0] = -1`` (sensor_msgs' convention for "unknown").
- ``scale`` Vector3Stamped: x = s, y = its 1-sigma (s * sigma of log s), z = sigma of log s
  (relative); y = z = -1 when no uncertainty was estimated.
- ``rms`` Vector3Stamped: x = the FRISICP error (both directions), y = forward (data -> model),
  z = backward (model -> data), model units.
- ``similarity`` Float64MultiArray: the (m+1)x(m+1) matrix [[s R, t], [0, 1]], row-major,
  layout.dim = [rows (size m+1, stride (m+1)^2), cols (size m+1, stride m+1)], data_offset 0.
  The one output without a header: std_msgs has no stamped matrix (``pose`` + ``scale`` are the
  same similarity, stamped).
- ``aligned`` PointCloud2: the data cloud mapped into the model frame, other fields kept.
- ``/tf`` (not under ``~``; :func:`tf_message`) tf2_msgs/TFMessage with one transform from the
  model frame to "the data frame scaled by s" (child frame ``tf_child_frame``, by default
  ``<data frame>_scaled``): a point p of the data frame is s * p in that frame, and (R, t) is then
  a rigid transform, as /tf requires.

Every stamped output carries the data cloud's header stamp.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from frisicp_core import RegistrationResult, Similarity
from frisicp_ros.stream.messages import HeaderLike, PointCloud2Like
from frisicp_ros.stream.pipeline import Registered
from frisicp_ros.stream.pointcloud2 import CloudParts, aligned_cloud
from frisicp_ros.stream.stamps import split_ns

OUTPUT_TOPICS: dict[str, str] = {
    "transform": "geometry_msgs/msg/TransformStamped",
    "pose": "geometry_msgs/msg/PoseWithCovarianceStamped",
    "scale": "geometry_msgs/msg/Vector3Stamped",
    "rms": "geometry_msgs/msg/Vector3Stamped",
    "similarity": "std_msgs/msg/Float64MultiArray",
    "aligned": "sensor_msgs/msg/PointCloud2",
}
# Every topic except ``aligned`` is produced for every reliable registered pair; an unreliable
# result (implausible, see frisicp_core.verdict) has no outputs: it is reported, not published.
ALWAYS_PUBLISHED = ("transform", "pose", "scale", "rms", "similarity")
TF_TYPE = "tf2_msgs/msg/TFMessage"
# Suffix of the default /tf child frame: "<data frame>_scaled" (see the module doc).
SCALED_FRAME_SUFFIX = "_scaled"
UNKNOWN = -1.0  # a standard deviation or covariance that was not estimated
# Every type the outputs are built of, parts included (and TF_TYPE, where it is available).
OUTPUT_MESSAGE_TYPES = (
    "builtin_interfaces/msg/Time",
    "std_msgs/msg/Header",
    "geometry_msgs/msg/Vector3",
    "geometry_msgs/msg/Point",
    "geometry_msgs/msg/Quaternion",
    "geometry_msgs/msg/Transform",
    "geometry_msgs/msg/Pose",
    "geometry_msgs/msg/PoseWithCovariance",
    "std_msgs/msg/MultiArrayDimension",
    "std_msgs/msg/MultiArrayLayout",
    "sensor_msgs/msg/PointField",
    *OUTPUT_TOPICS.values(),
)


@dataclass(frozen=True)
class MessageTypes:
    """Message classes by ROS type name, plus how each flavour wants its array fields."""

    classes: dict[str, type]
    uint8_array: Callable[[np.ndarray], Any]
    float64_array: Callable[[np.ndarray], Any]

    def __getitem__(self, type_name: str) -> type:
        return self.classes[type_name]

    def __contains__(self, type_name: object) -> bool:
        return type_name in self.classes

    def header(self, stamp_ns: int, frame_id: str) -> Any:
        """A header at ``stamp_ns`` nanoseconds (normalised: 0 <= nanosec < 1e9)."""
        return self.stamped_header(split_ns(stamp_ns), frame_id)

    def stamped_header(self, stamp: tuple[int, int], frame_id: str) -> Any:
        """A header with the (sec, nanosec) of a received stamp, copied as they are."""
        sec, nanosec = stamp
        time_msg = self["builtin_interfaces/msg/Time"](sec=int(sec), nanosec=int(nanosec))
        return self["std_msgs/msg/Header"](stamp=time_msg, frame_id=frame_id)

    def point_cloud(self, parts: CloudParts, header: HeaderLike) -> Any:
        field_class = self["sensor_msgs/msg/PointField"]
        fields = [
            field_class(name=f.name, offset=f.offset, datatype=f.datatype, count=f.count)
            for f in parts.fields
        ]
        return self["sensor_msgs/msg/PointCloud2"](
            header=header,
            height=parts.height,
            width=parts.width,
            fields=fields,
            is_bigendian=parts.is_bigendian,
            point_step=parts.point_step,
            row_step=parts.row_step,
            data=self.uint8_array(parts.data),
            is_dense=parts.is_dense,
        )


def rosbags_message_types(typestore: Any = None) -> MessageTypes:
    """The rosbags classes of ``typestore`` (default: the ROS 2 Jazzy store)."""
    if typestore is None:
        from rosbags.typesys import Stores, get_typestore

        typestore = get_typestore(Stores.ROS2_JAZZY)
    classes = {name: typestore.types[name] for name in (*OUTPUT_MESSAGE_TYPES, TF_TYPE)}
    return MessageTypes(
        classes,
        lambda values: np.ascontiguousarray(values, dtype=np.uint8),
        lambda values: np.ascontiguousarray(values, dtype=np.float64),
    )


def _rigid_part(similarity: Similarity, types: MessageTypes) -> tuple[Any, Any]:
    """(translation as Vector3-like values, rotation as a Quaternion) of (R, t), embedded in 3-D."""
    rigid = _rigid_3d(similarity)
    x, y, z, w = rigid.quaternion()
    quaternion = types["geometry_msgs/msg/Quaternion"](x=float(x), y=float(y), z=float(z), w=float(w))
    return tuple(float(v) for v in rigid.translation), quaternion


def transform_stamped(
    similarity: Similarity, header: HeaderLike, child_frame_id: str, types: MessageTypes
) -> Any:
    (x, y, z), quaternion = _rigid_part(similarity, types)
    transform = types["geometry_msgs/msg/Transform"](
        translation=types["geometry_msgs/msg/Vector3"](x=x, y=y, z=z), rotation=quaternion
    )
    return types["geometry_msgs/msg/TransformStamped"](
        header=header, child_frame_id=child_frame_id, transform=transform
    )


def pose_covariance(result: RegistrationResult) -> np.ndarray:
    """The 6x6 covariance of ``~/pose`` (x y z roll pitch yaw): the core's
    ``Uncertainty.pose_covariance``; without an estimate all zero but [0, 0] = -1 (unknown)."""
    if result.uncertainty is None:
        unknown = np.zeros((6, 6))
        unknown[0, 0] = UNKNOWN
        return unknown
    return np.asarray(result.uncertainty.pose_covariance(result.similarity), dtype=np.float64)


def pose_with_covariance(result: RegistrationResult, header: HeaderLike, types: MessageTypes) -> Any:
    (x, y, z), quaternion = _rigid_part(result.similarity, types)
    pose = types["geometry_msgs/msg/Pose"](
        position=types["geometry_msgs/msg/Point"](x=x, y=y, z=z), orientation=quaternion
    )
    with_covariance = types["geometry_msgs/msg/PoseWithCovariance"](
        pose=pose, covariance=types.float64_array(pose_covariance(result).reshape(-1))
    )
    return types["geometry_msgs/msg/PoseWithCovarianceStamped"](header=header, pose=with_covariance)


def scale_sigma(result: RegistrationResult) -> tuple[float, float]:
    """(absolute, relative) 1-sigma of the scale; (-1, -1) when not estimated."""
    if result.uncertainty is None:
        return UNKNOWN, UNKNOWN
    relative = result.uncertainty.scale
    return result.similarity.scale * relative, relative


def vector3_stamped(values: tuple[float, float, float], header: HeaderLike, types: MessageTypes) -> Any:
    x, y, z = (float(v) for v in values)
    vector = types["geometry_msgs/msg/Vector3"](x=x, y=y, z=z)
    return types["geometry_msgs/msg/Vector3Stamped"](header=header, vector=vector)


def scaled_frame(data_frame: str, configured: str = "") -> str:
    """The /tf child frame: ``configured``, or "<data frame>_scaled" when that is empty."""
    return configured or f"{data_frame}{SCALED_FRAME_SUFFIX}"


def tf_message(outcome: Registered, child_frame_id: str, types: MessageTypes) -> Any:
    """A TFMessage with (R, t) from the model frame to ``child_frame_id`` (the data frame scaled by
    s), stamped with the data cloud's stamp. Raises ValueError for an unreliable result."""
    _require_publishable(outcome)
    header = types.stamped_header(outcome.stamp, outcome.model_frame)
    transform = transform_stamped(outcome.result.similarity, header, child_frame_id, types)
    return types[TF_TYPE](transforms=[transform])


def _rigid_3d(similarity: Similarity) -> Similarity:
    """The rotation and translation (scale 1) embedded in 3-D (a 2-D rotation turns about z)."""
    if similarity.dim == 3:
        return Similarity(1.0, similarity.rotation, similarity.translation)
    rotation, translation = np.eye(3), np.zeros(3)
    rotation[:2, :2] = similarity.rotation
    translation[:2] = similarity.translation
    return Similarity(1.0, rotation, translation)


def similarity_matrix(similarity: Similarity, types: MessageTypes) -> Any:
    size = similarity.dim + 1
    dims = [
        types["std_msgs/msg/MultiArrayDimension"](label="rows", size=size, stride=size * size),
        types["std_msgs/msg/MultiArrayDimension"](label="cols", size=size, stride=size),
    ]
    layout = types["std_msgs/msg/MultiArrayLayout"](dim=dims, data_offset=0)
    return types["std_msgs/msg/Float64MultiArray"](
        layout=layout, data=types.float64_array(similarity.matrix().reshape(-1))
    )


def build_outputs(
    outcome: Registered,
    data_cloud: PointCloud2Like,
    types: MessageTypes,
    topics: tuple[str, ...] = ALWAYS_PUBLISHED,
) -> dict[str, Any]:
    """Messages for the requested topic suffixes (subset of OUTPUT_TOPICS) of a registered pair.

    ``data_cloud`` is the pair's data message (``aligned`` is a copy of it with new coordinates).
    Every message carries the data cloud's stamp; frames come from the clouds.
    """
    _require_publishable(outcome)
    unknown = set(topics) - set(OUTPUT_TOPICS)
    if unknown:
        raise ValueError(f"unknown output topics {sorted(unknown)}; known: {sorted(OUTPUT_TOPICS)}")
    result = outcome.result
    similarity = result.similarity

    def header() -> Any:  # one per message: rclpy messages own their fields
        return types.stamped_header(outcome.stamp, outcome.model_frame)

    builders: dict[str, Callable[[], Any]] = {
        "transform": lambda: transform_stamped(similarity, header(), outcome.data_frame, types),
        "pose": lambda: pose_with_covariance(result, header(), types),
        "scale": lambda: vector3_stamped((similarity.scale, *scale_sigma(result)), header(), types),
        "rms": lambda: vector3_stamped(
            (result.rms, result.forward_rms, result.backward_rms), header(), types
        ),
        "similarity": lambda: similarity_matrix(similarity, types),
        "aligned": lambda: aligned_cloud(
            data_cloud, similarity, outcome.dims, lambda parts: types.point_cloud(parts, header())
        ),
    }
    return {topic: builders[topic]() for topic in topics}


def _require_publishable(outcome: Registered) -> None:
    if not isinstance(outcome, Registered):  # the type says so; untyped callers hear it too
        raise ValueError(f"rejected pair has no outputs: {getattr(outcome, 'reason', outcome)}")
    if not outcome.reliable:  # the one gate in front of every publisher and result bag
        raise ValueError(f"an unreliable result has no outputs: {outcome.reason}")


def result_summary(result: RegistrationResult) -> dict[str, object]:
    """The result as JSON-ready values (``frisicp register --json`` and the bag mode's lines).

    ``reliable`` False (with ``reason``) marks a result that failed the plausibility checks.
    ``depth_averaged``, only where done: the voxel edges [data, model] both clouds were averaged
    over (``frisicp_core.terraces``).
    """
    sim = result.similarity
    summary: dict[str, object] = {
        "scale": sim.scale,
        "rotation": sim.rotation.tolist(),
        "translation": sim.translation.tolist(),
        "rms": result.rms,
        "iterations": sum(result.iterations),
        "converged": result.converged,
        "reliable": result.reliable,
        "reason": result.reason,
        "overlap_forward": result.overlap_forward,
        "overlap_backward": result.overlap_backward,
        "warm_started": result.warm_started,
        "retried": result.retried,  # why a warm start was retried cold ('' when it was not)
        "seconds": result.seconds,
        "uncertainty": uncertainty_summary(result),
    }
    if sim.dim == 3:
        summary["quaternion_xyzw"] = sim.quaternion().tolist()
    if result.depth_averaged is not None:  # voxel edges [data, model]: frisicp_core.terraces
        summary["depth_averaged"] = list(result.depth_averaged)
    return summary


def uncertainty_summary(result: RegistrationResult) -> dict[str, float] | None:
    """The 1-sigma summary of the result's uncertainty (None when not estimated): ``scale``
    relative (sigma of log s), ``rotation_deg``, ``translation`` (model units, where the data's
    centroid lands)."""
    if result.uncertainty is None:
        return None
    u = result.uncertainty
    return {"scale": u.scale, "rotation_deg": u.rotation_deg, "translation": u.translation}
