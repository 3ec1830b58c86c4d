"""The shared pipeline without ROS: pairing, registration of messages, outputs in both flavours."""

from __future__ import annotations

import numpy as np
import pytest
from support.data import axis_rotation

from frisicp_core import Similarity, bumpy_surface, closed_contour, register
from frisicp_core.points import rms_radius
from frisicp_core.sampling import needs_spatial_order, spatial_order
from frisicp_ros.node.message_types import rclpy_message_types
from frisicp_ros.stream.outputs import (
    OUTPUT_TOPICS,
    build_outputs,
    result_summary,
    rosbags_message_types,
)
from frisicp_ros.stream.pairing import Pairer
from frisicp_ros.stream.pipeline import Registered, RegistrationPipeline, Rejected
from frisicp_ros.stream.pointcloud2 import cloud_to_points, points_to_parts
from frisicp_ros.stream.settings import PipelineSettings

TRUTH = Similarity(1.8, axis_rotation(3, 25.0), np.array([0.4, -0.2, 1.0]))


def cloud(points, frame: str, stamp_ns: int, types=None, **extra):
    types = types or rosbags_message_types()
    return types.point_cloud(points_to_parts(points, extra or None), types.header(stamp_ns, frame))


def scene(n: int = 3000, stamp_ns: int = 5_000_000_123, types=None):
    """(model msg, data msg) with model = TRUTH(data) exactly."""
    data = bumpy_surface(n, seed=3)
    return (
        cloud(TRUTH.apply(data), "map", stamp_ns - 10**8, types),
        cloud(data, "lidar", stamp_ns, types, intensity=np.arange(n, dtype=np.float32)),
    )


# --- pairing -------------------------------------------------------------------------------------


def test_latest_model_pairs_each_data_with_newest_model():
    pairer: Pairer[str, str] = Pairer("latest_model")
    assert pairer.add_data(1, "d0") == [] and pairer.unpaired_data == 1
    assert pairer.add_model(2, "m1") == []
    assert pairer.add_data(3, "d1") == [("m1", "d1")]
    pairer.add_model(4, "m2")
    assert pairer.add_data(5, "d2") == [("m2", "d2")]
    assert pairer.add_data(6, "d3") == [("m2", "d3")]  # a map is reused
    pairer.reset()
    assert pairer.latest_model is None and pairer.add_data(7, "d4") == []


def test_synchronized_pairs_by_stamp_within_tolerance_in_either_arrival_order():
    ms = 1_000_000
    pairer: Pairer[str, str] = Pairer("synchronized", tolerance_sec=0.01)
    assert pairer.add_model(100 * ms, "m100") == []
    assert pairer.add_data(130 * ms, "d130") == []  # 30 ms: outside the tolerance, waits
    assert pairer.add_data(104 * ms, "d104") == [("m100", "d104")]
    assert pairer.add_data(205 * ms, "d205") == []  # data first ...
    assert pairer.add_model(200 * ms, "m200") == [("m200", "d205")]  # ... model completes it
    assert pairer.unpaired_data == 1  # d130 was older than the completed pair and is gone
    assert pairer.add_model(400 * ms, "m400") == []
    assert pairer.add_data(300 * ms, "d300") == []
    with pytest.raises(ValueError, match="pairing mode"):
        Pairer("newest")


def test_changing_mode_or_tolerance_keeps_the_stored_model_and_the_counter():
    """A latched map arrives once: a parameter change must not forget it."""
    pairer: Pairer[str, str] = Pairer("latest_model")
    pairer.add_data(1, "early")
    pairer.add_model(2, "map")
    pairer.reconfigure("latest_model", 0.2)
    assert pairer.add_data(3, "d1") == [("map", "d1")] and pairer.unpaired_data == 1
    pairer.reconfigure("synchronized", 10.0)
    assert pairer.add_data(4, "d2") == [("map", "d2")]
    pairer.add_data(50 * 10**9, "waiting")  # no model within the tolerance: buffered
    pairer.add_model(100 * 10**9, "map2")
    pairer.reconfigure("latest_model", 0.05)  # the waiting data cloud can never pair now
    assert pairer.unpaired_data == 2 and pairer.latest_model == "map2"
    with pytest.raises(ValueError, match="pairing mode"):
        pairer.reconfigure("newest", 0.1)


# --- pipeline ------------------------------------------------------------------------------------


def test_pipeline_recovers_the_similarity_and_reports_timings():
    model_msg, data_msg = scene()
    pipeline = RegistrationPipeline(PipelineSettings.create(max_points=2000))
    outcome = pipeline.process(model_msg, data_msg)
    assert isinstance(outcome, Registered), outcome
    sim = outcome.result.similarity
    assert sim.scale == pytest.approx(TRUTH.scale, rel=1e-3)
    np.testing.assert_allclose(sim.rotation, TRUTH.rotation, atol=2e-3)
    assert (outcome.stamp_ns, outcome.model_frame, outcome.data_frame) == (5_000_000_123, "map", "lidar")
    assert outcome.data_points == 2000 and not outcome.warm_started
    assert outcome.timings.convert_seconds > 0 and outcome.timings.register_seconds > 0
    again = pipeline.process(model_msg, data_msg)
    assert (
        isinstance(again, Registered)
        and again.warm_started
        and again.result.similarity.scale == pytest.approx(TRUTH.scale, rel=1e-3)
    )
    pipeline.reset()
    assert pipeline.previous is None


def test_a_jump_in_a_tracked_stream_is_retried_cold_and_never_published_wrong():
    """Issue 14: the node, replay and frisicp bag share this pipeline. After a jump of 120 deg
    (relocalisation, a swapped sensor) the warm start from the track falls into a wrong minimum;
    the pipeline hands the core its track, the core retries cold, and the pair comes out right
    and reliable, the track following the new pose."""
    model_points = bumpy_surface(12000, seed=1)
    whole = bumpy_surface(6000, seed=5)
    first = Similarity(1.7, axis_rotation(3, 17.0), np.array([0.2, -0.1, 0.4]))
    turn = Similarity.about(model_points.mean(axis=0), 1.0, axis_rotation(3, 120.0, (1.0, 0.4, -0.3)))
    model_msg = cloud(model_points, "map", 1_000_000_000)
    pipeline = RegistrationPipeline(PipelineSettings.create(max_points=3000))
    stamp = 2_000_000_000
    outcomes = []
    for truth in (first, first, turn @ first, turn @ first):
        outcome = pipeline.process(model_msg, cloud(truth.inverse().apply(whole), "lidar", stamp))
        stamp += 100_000_000
        assert isinstance(outcome, Registered) and outcome.reliable, outcome
        error = outcome.result.similarity @ truth.inverse()
        assert np.degrees(error.rotation_angle()) < 1.0 and abs(error.scale - 1.0) < 0.01
        outcomes.append(outcome)
    tracked, jumped, after = outcomes[1:]
    assert tracked.warm_started and not tracked.result.retried
    assert jumped.result.retried.startswith("warm start retried cold") and not jumped.warm_started
    assert after.warm_started and not after.result.retried  # the track follows the new pose
    assert result_summary(jumped.result)["retried"] == jumped.result.retried  # in every JSON line


def test_model_is_prepared_once_per_message_at_full_resolution():
    """max_points caps data clouds only: the model is the core's PreparedModel of all its points,
    made for the first pair and reused by the next (its tree too)."""
    model_msg, data_msg = scene(3000)
    pipeline = RegistrationPipeline(PipelineSettings.create(max_points=2500))
    first = pipeline.process(model_msg, data_msg)
    assert isinstance(first, Registered)
    cached = pipeline._model_cache
    assert cached is not None and cached[0] is model_msg
    prepared = cached[1]
    assert len(prepared) == 3000 and first.model_points == 3000 and first.data_points == 2500
    assert not needs_spatial_order(prepared.points, rms_radius(prepared.points))
    np.testing.assert_array_equal(prepared.points[spatial_order(prepared.points)], prepared.points)
    tree = prepared.tree()
    second = pipeline.process(model_msg, data_msg)
    assert isinstance(second, Registered) and pipeline._model_cache is cached  # not read again
    assert prepared.tree() is tree
    assert second.timings.input_seconds < first.timings.input_seconds  # the data cloud only
    assert first.timings.register_cpu_seconds > 0
    # the same answer as the core given the whole model as an array
    settings = PipelineSettings.create(max_points=2500, warm_start=False)
    raw = register(
        cloud_to_points(data_msg, 3, 2500), cloud_to_points(model_msg, 3, None), settings.registration
    )
    fresh = RegistrationPipeline(settings).process(model_msg, data_msg)
    assert isinstance(fresh, Registered)
    np.testing.assert_array_equal(fresh.result.similarity.matrix(), raw.similarity.matrix())


def test_changing_voxels_or_cap_forgets_the_model_and_the_warm_start():
    model_msg, data_msg = scene(3000)
    pipeline = RegistrationPipeline(PipelineSettings.create(max_points=2000))
    pipeline.process(model_msg, data_msg)
    assert pipeline.previous is not None
    pipeline.update_settings(pipeline.settings.updated(voxel_size=0.15))
    assert pipeline.previous is None and pipeline._model_cache is None
    outcome = pipeline.process(model_msg, data_msg)
    assert isinstance(outcome, Registered) and outcome.data_points < 2000  # the grid thinned it
    assert outcome.result.similarity.scale == pytest.approx(TRUTH.scale, rel=1e-2)
    # The voxels' means instead of their first points: other clouds, so forgotten too.
    pipeline.update_settings(pipeline.settings.updated(voxel_mode="centroid"))
    assert pipeline.previous is None and pipeline._model_cache is None
    averaged = pipeline.process(model_msg, data_msg)
    assert isinstance(averaged, Registered) and averaged.data_points == outcome.data_points
    assert averaged.result.similarity.scale == pytest.approx(TRUTH.scale, rel=1e-2)
    with pytest.raises(ValueError, match="voxel_mode must be one of first, centroid"):
        pipeline.settings.updated(voxel_mode="median")


def test_pipeline_2d_mode_registers_planar_scans():
    data = closed_contour(800)
    truth = Similarity(0.6, axis_rotation(2, 40.0), np.array([1.0, 2.0]))
    zeros = np.zeros((800, 1))
    outcome = RegistrationPipeline(PipelineSettings.create(dims=2)).process(
        cloud(np.hstack([truth.apply(data), zeros]), "map", 10), cloud(np.hstack([data, zeros]), "scan", 10)
    )
    assert isinstance(outcome, Registered), outcome
    assert outcome.result.similarity.scale == pytest.approx(0.6, rel=1e-3)


def test_pipeline_rejects_bad_input_with_reasons_and_recovers():
    model_msg, data_msg = scene(500)
    pipeline = RegistrationPipeline(PipelineSettings.create(pairing="synchronized"))
    nan_cloud = cloud(np.full((50, 3), np.nan), "lidar", 1)
    line = cloud(np.outer(np.arange(100.0), [1.0, 2.0, 3.0]), "lidar", 1)
    assert rejected_input(pipeline.process(model_msg, nan_cloud)) == "data"
    assert rejected_input(pipeline.process(nan_cloud, data_msg)) == "model"
    degenerate = pipeline.process(model_msg, line)
    assert isinstance(degenerate, Rejected)
    assert degenerate.input == "pair" and "collinear" in degenerate.reason
    line_model = pipeline.process(cloud(np.outer(np.arange(100.0), [1.0, 2.0, 3.0]), "map", 1), data_msg)
    assert isinstance(line_model, Rejected)
    assert line_model.input == "model" and "collinear" in line_model.reason
    assert isinstance(pipeline.process(model_msg, data_msg), Registered)
    moved = pipeline.process(model_msg, cloud(bumpy_surface(500), "other_lidar", 2))
    assert isinstance(moved, Rejected) and "frame mismatch" in moved.reason
    assert isinstance(pipeline.process(model_msg, data_msg), Registered)


def test_clouds_in_large_units_register_in_the_node_and_the_bag_mode_alike():
    """The data in units 1e80 times the model's (float64 fields) was rejected as "unexpected
    IndexError" here and crashed `frisicp register`; all three now register it."""
    from frisicp_ros.stream.pointcloud2 import FLOAT64

    data = bumpy_surface(1500, seed=3)
    model_msg = cloud(TRUTH.apply(data), "map", 10)
    types = rosbags_message_types()
    data_msg = types.point_cloud(points_to_parts(data * 1e80, datatype=FLOAT64), types.header(10, "lidar"))
    outcome = RegistrationPipeline(PipelineSettings.create(max_points=0)).process(model_msg, data_msg)
    assert isinstance(outcome, Registered) and outcome.reliable, outcome
    assert outcome.result.similarity.scale == pytest.approx(TRUTH.scale * 1e-80, rel=1e-9)
    np.testing.assert_allclose(outcome.result.similarity.translation, TRUTH.translation, atol=1e-9)


def rejected_input(outcome: object) -> str:
    assert isinstance(outcome, Rejected), outcome
    return outcome.input


def test_settings_validate_through_the_table_and_the_core():
    with pytest.raises(ValueError, match="overlap"):
        PipelineSettings.create(overlap=1.5)
    with pytest.raises(ValueError, match="dims"):
        PipelineSettings.create(dims=4)
    with pytest.raises(ValueError, match="method must be one of"):
        PipelineSettings.create().updated(method="ransac")
    with pytest.raises(ValueError, match=r"relative_motion must be in \[0, 1\)"):  # the core's own check
        PipelineSettings.create(relative_motion=1.0)
    config = PipelineSettings.create(max_distance=0.0).registration
    assert config.max_distance is None  # 0 stands for the core's None


# --- outputs -------------------------------------------------------------------------------------


@pytest.mark.parametrize("flavour", [rclpy_message_types, rosbags_message_types])
def test_outputs_carry_data_stamp_frames_and_the_similarity(flavour):
    types = flavour()
    model_msg, data_msg = scene(1500, types=types)
    outcome = RegistrationPipeline().process(model_msg, data_msg)
    messages = build_outputs(outcome, data_msg, types, tuple(OUTPUT_TOPICS))
    transform = messages["transform"]
    assert (transform.header.stamp.sec, transform.header.stamp.nanosec) == (5, 123)
    assert (transform.header.frame_id, transform.child_frame_id) == ("map", "lidar")
    q = transform.transform.rotation
    sim = outcome.result.similarity
    rebuilt = Similarity.from_quaternion(
        messages["scale"].vector.x,
        [q.x, q.y, q.z, q.w],
        [
            transform.transform.translation.x,
            transform.transform.translation.y,
            transform.transform.translation.z,
        ],
    )
    np.testing.assert_allclose(rebuilt.matrix(), sim.matrix(), atol=1e-9)
    matrix = messages["similarity"]
    assert [(d.label, d.size, d.stride) for d in matrix.layout.dim] == [("rows", 4, 16), ("cols", 4, 4)]
    np.testing.assert_allclose(np.asarray(matrix.data).reshape(4, 4), sim.matrix())
    assert messages["rms"].vector.x == pytest.approx(outcome.result.rms)
    aligned = messages["aligned"]
    assert aligned.header.frame_id == "map" and [f.name for f in aligned.fields] == [
        "x",
        "y",
        "z",
        "intensity",
    ]
    np.testing.assert_allclose(
        np.frombuffer(aligned.data, np.float32).reshape(-1, 4)[:, :3],
        TRUTH.apply(bumpy_surface(1500, seed=3)),
        atol=1e-3,
    )


def test_rosbags_outputs_serialize_with_the_jazzy_typestore():
    from rosbags.typesys import Stores, get_typestore

    typestore = get_typestore(Stores.ROS2_JAZZY)
    types = rosbags_message_types(typestore)
    model_msg, data_msg = scene(1000, types=types)
    outcome = RegistrationPipeline().process(model_msg, data_msg)
    for topic, message in build_outputs(outcome, data_msg, types, tuple(OUTPUT_TOPICS)).items():
        raw = typestore.serialize_cdr(message, OUTPUT_TOPICS[topic])
        assert typestore.deserialize_cdr(raw, OUTPUT_TOPICS[topic]).__msgtype__ == OUTPUT_TOPICS[topic]


def test_rejected_outcome_has_no_outputs():
    nan_cloud = cloud(np.full((5, 3), np.nan), "lidar", 1)
    outcome = RegistrationPipeline().process(*scene(100)[:1], nan_cloud)
    with pytest.raises(ValueError, match="no outputs"):
        build_outputs(outcome, nan_cloud, rosbags_message_types())  # type: ignore[arg-type]


def test_2d_outputs_are_a_rotation_about_z_and_a_3x3_matrix():
    types = rosbags_message_types()
    data = closed_contour(600)
    truth = Similarity(2.0, axis_rotation(2, 30.0), np.array([1.0, -1.0]))
    zeros = np.zeros((600, 1))
    scan = cloud(np.hstack([data, zeros + 5.0]), "scan", 20)
    outcome = RegistrationPipeline(PipelineSettings.create(dims=2)).process(
        cloud(np.hstack([truth.apply(data), zeros]), "map", 10), scan
    )
    messages = build_outputs(outcome, scan, types, tuple(OUTPUT_TOPICS))
    q = messages["transform"].transform.rotation
    assert (q.x, q.y) == (0.0, 0.0) and np.degrees(2 * np.arctan2(q.z, q.w)) == pytest.approx(30.0, abs=0.05)
    assert messages["transform"].transform.translation.z == 0.0
    matrix = messages["similarity"]
    assert [(d.size, d.stride) for d in matrix.layout.dim] == [(3, 9), (3, 3)]
    np.testing.assert_allclose(matrix.data.reshape(3, 3), truth.matrix(), atol=2e-3)
    aligned = np.frombuffer(messages["aligned"].data, np.float32).reshape(-1, 3)
    np.testing.assert_allclose(aligned[:, :2], truth.apply(data), atol=1e-2)
    assert np.all(aligned[:, 2] == 5.0)  # 2-D mode leaves z alone
