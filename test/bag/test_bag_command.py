"""`frisicp bag` and `frisicp bag-info` on bags written by rosbags and by Foxglove's mcap writer."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from support.bags import (
    DATA_FRAME,
    DATA_TOPIC,
    MODEL_FRAME,
    MODEL_TOPIC,
    OTHER_TOPIC,
    CloudRecord,
    Scenario,
    assert_matches_truth,
    data_cloud,
    standard_scenario,
    truth_for,
    write_mcap_ros2,
    write_ros1_bag,
    write_rosbag2,
)
from support.scripts import installed_script

from frisicp_core import Similarity, bumpy_surface
from frisicp_ros.cli import main as cli

POINTS = 800
REPO = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def scenario() -> Scenario:
    return standard_scenario(POINTS)


@pytest.fixture(scope="module")
def bags(tmp_path_factory, scenario) -> dict[str, Path]:
    """The same recording in every format the bag mode reads."""
    root = tmp_path_factory.mktemp("bags")
    return {
        "rosbags-sqlite3": write_rosbag2(
            root / "sqlite_bag", scenario.records, "sqlite3", extra_string_topic=True
        ),
        "rosbags-mcap": write_rosbag2(root / "mcap_bag", scenario.records, "mcap"),
        "rosbags-db3-file": write_rosbag2(root / "db3_file", scenario.records, "sqlite3") / "db3_file.db3",
        "foxglove-mcap-file": write_mcap_ros2(root / "foxglove.mcap", scenario.records),
        "rosbags-ros1": write_ros1_bag(root / "ros1.bag", scenario.records),
    }


def run_cli(capsys, *argv: str) -> tuple[int, str, str]:
    code = cli.main([str(a) for a in argv])
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def bag_args(bag: Path, *extra: str) -> list[str]:
    return ["bag", str(bag), "--model-topic", MODEL_TOPIC, "--data-topic", DATA_TOPIC, *extra]


def rotation_angle_deg(matrix) -> float:
    return float(np.degrees(np.arccos(np.clip((np.trace(matrix) - 1) / 2, -1.0, 1.0))))


def stamp_ns_of(header) -> int:
    return header.stamp.sec * 10**9 + header.stamp.nanosec


def read_jsonl(text: str) -> list[dict]:
    return [json.loads(line) for line in text.splitlines() if line.strip()]


# --- bag-info ----------------------------------------------------------------------------------


def test_bag_info_lists_topics_types_counts_and_marks_pointcloud2(capsys, bags):
    code, out, _ = run_cli(capsys, "bag-info", bags["rosbags-sqlite3"])
    assert code == 0
    lines = {line.split()[0]: line for line in out.splitlines() if line.startswith("/")}
    assert set(lines) == {MODEL_TOPIC, DATA_TOPIC, OTHER_TOPIC}
    assert "sensor_msgs/msg/PointCloud2" in lines[DATA_TOPIC] and " 4 " in lines[DATA_TOPIC] + " "
    assert "PointCloud2" in lines[MODEL_TOPIC].split()[-1]
    assert "std_msgs/msg/String" in lines[OTHER_TOPIC] and "<-" not in lines[OTHER_TOPIC]
    code, out, _ = run_cli(capsys, "bag-info", "--json", bags["rosbags-sqlite3"])
    info = json.loads(out)
    assert info["messages"] == 8
    by_name = {t["name"]: t for t in info["topics"]}
    assert by_name[DATA_TOPIC] == {
        "name": DATA_TOPIC,
        "type": "sensor_msgs/msg/PointCloud2",
        "count": 4,
        "pointcloud2": True,
    }
    assert by_name[OTHER_TOPIC]["pointcloud2"] is False


# --- correct results from every format ------------------------------------------------------


@pytest.mark.parametrize(
    "kind", ["rosbags-sqlite3", "rosbags-mcap", "rosbags-db3-file", "foxglove-mcap-file", "rosbags-ros1"]
)
def test_latest_model_pairs_every_data_cloud_and_recovers_the_truth(capsys, bags, scenario, kind):
    code, out, err = run_cli(capsys, *bag_args(bags[kind]))
    assert code == 0, err
    records = read_jsonl(out)
    data = scenario.data_records()
    assert [r["stamp_ns"] for r in records] == [d.bag_ns for d in data]
    assert [r["header_stamp_ns"] for r in records] == [d.header_ns for d in data]
    assert [r["model_stamp_ns"] for r in records] == [scenario.source_model_ns[d.bag_ns] for d in data]
    assert [r["pair"] for r in records] == list(range(len(data)))
    for record in records:
        assert (record["model_frame"], record["data_frame"]) == (MODEL_FRAME, DATA_FRAME)
        assert record["iterations"] == sum(record["iterations_per_level"]) >= 1
        assert record["seconds"] > 0 and record["rms"] >= 0
        assert_matches_truth(record, scenario.truth[record["stamp_ns"]])
    assert "pairs 4 (rejected 0, unreliable 0), converged 4, median RMS" in err


def test_synchronized_pairs_only_matching_stamps(capsys, bags, scenario):
    code, out, err = run_cli(
        capsys, *bag_args(bags["rosbags-mcap"], "--pairing", "synchronized", "--sync-tolerance", "0.1")
    )
    assert code == 0, err
    records = read_jsonl(out)
    # The 2.5 s data cloud has no model within 0.1 s: it is left out.
    assert [r["header_stamp_ns"] for r in records] == [1_000_000_000, 2_000_000_000, 3_000_000_000]
    assert [r["model_stamp_ns"] for r in records] == [r["header_stamp_ns"] for r in records]
    for record in records:
        assert_matches_truth(record, scenario.truth[record["stamp_ns"]])
    assert "pairs 3" in err and "1 data clouds found no model" in err
    assert "registering: 100%" in err and "4/4" in err  # tqdm's bar, counted in data clouds


def test_jobs_2_gives_the_results_of_jobs_1_in_bag_order(capsys, bags, tmp_path):
    outputs = {}
    for jobs in ("1", "2"):
        target = tmp_path / f"jobs{jobs}.jsonl"
        code, _, err = run_cli(
            capsys,
            *bag_args(
                bags["foxglove-mcap-file"],
                "--no-warm-start",
                "--jobs",
                jobs,
                "--out",
                target,
                "--no-progress",
            ),
        )
        assert code == 0, err
        outputs[jobs] = [
            {k: v for k, v in r.items() if k != "seconds"} for r in read_jsonl(target.read_text())
        ]
    assert len(outputs["1"]) == 4
    assert outputs["2"] == outputs["1"]


def test_jobs_2_with_warm_start_warm_starts_within_chunks_of_pairs(capsys, bags, scenario, tmp_path):
    """No refusal: --jobs 2 keeps the warm start within chunks of consecutive pairs and says so.
    The 4 pairs here fit in one chunk, so the results are exactly those of --jobs 1."""
    outputs = {}
    for jobs in ("1", "2"):
        target = tmp_path / f"warm{jobs}.jsonl"
        code, _, err = run_cli(
            capsys, *bag_args(bags["rosbags-mcap"], "--jobs", jobs, "--out", target, "--no-progress")
        )
        assert code == 0, err
        assert ("warm-starts within chunks of 8 consecutive pairs" in err) == (jobs == "2"), err
        outputs[jobs] = [
            {k: v for k, v in r.items() if k != "seconds"} for r in read_jsonl(target.read_text())
        ]
    assert outputs["2"] == outputs["1"] and len(outputs["1"]) == 4
    for record in outputs["2"]:
        assert_matches_truth(record, scenario.truth[record["stamp_ns"]])


def test_result_bag_reads_back_with_the_node_topics_and_original_stamps(capsys, bags, scenario, tmp_path):
    from rosbags.highlevel import AnyReader

    from frisicp_ros.stream.pointcloud2 import cloud_to_points

    out_bag = tmp_path / "results"
    code, out, err = run_cli(capsys, *bag_args(bags["rosbags-sqlite3"], "--out-bag", out_bag))
    assert code == 0, err
    records = {r["stamp_ns"]: r for r in read_jsonl(out)}
    assert sorted(p.name for p in out_bag.iterdir()) == ["metadata.yaml", "results.mcap"]
    assert not list(tmp_path.glob("results.partial-*")), "the staging folder must be gone"
    with AnyReader([out_bag]) as reader:
        assert {t: i.msgtype for t, i in reader.topics.items()} == {
            "/frisicp/transform": "geometry_msgs/msg/TransformStamped",
            "/frisicp/pose": "geometry_msgs/msg/PoseWithCovarianceStamped",
            "/frisicp/scale": "geometry_msgs/msg/Vector3Stamped",
            "/frisicp/rms": "geometry_msgs/msg/Vector3Stamped",
            "/frisicp/similarity": "std_msgs/msg/Float64MultiArray",
            "/frisicp/aligned": "sensor_msgs/msg/PointCloud2",
            "/tf": "tf2_msgs/msg/TFMessage",
        }
        seen: dict[str, list[int]] = {}
        for connection, stamp_ns, raw in reader.messages():
            msg = reader.deserialize(raw, connection.msgtype)
            record = records[stamp_ns]  # log time = the data cloud's bag time
            seen.setdefault(connection.topic, []).append(stamp_ns)
            suffix = connection.topic.rsplit("/", 1)[1]
            header_ns = None
            if suffix == "transform":
                header_ns = msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec
                assert header_ns == record["header_stamp_ns"]
                assert (msg.header.frame_id, msg.child_frame_id) == (MODEL_FRAME, DATA_FRAME)
                q = msg.transform.rotation
                np.testing.assert_allclose([q.x, q.y, q.z, q.w], record["quaternion_xyzw"], atol=1e-12)
                t = msg.transform.translation
                np.testing.assert_allclose([t.x, t.y, t.z], record["translation"], atol=1e-12)
            elif suffix == "pose":
                assert (
                    stamp_ns_of(msg.header) == record["header_stamp_ns"]
                    and msg.header.frame_id == MODEL_FRAME
                )
                p, q = msg.pose.pose.position, msg.pose.pose.orientation
                np.testing.assert_allclose([p.x, p.y, p.z], record["translation"], atol=1e-12)
                np.testing.assert_allclose([q.x, q.y, q.z, q.w], record["quaternion_xyzw"], atol=1e-12)
                covariance = np.asarray(msg.pose.covariance).reshape(6, 6)
                assert np.all(np.diag(covariance) > 0) and np.allclose(covariance, covariance.T)
            elif suffix == "scale":
                assert stamp_ns_of(msg.header) == record["header_stamp_ns"]
                assert msg.vector.x == pytest.approx(record["scale"], rel=1e-12)
                sigma = record["uncertainty"]["scale"]
                assert (msg.vector.y, msg.vector.z) == pytest.approx((record["scale"] * sigma, sigma))
            elif suffix == "rms":
                assert msg.vector.x == pytest.approx(record["rms"], rel=1e-12)
            elif suffix == "tf":
                (transform,) = msg.transforms
                assert stamp_ns_of(transform.header) == record["header_stamp_ns"]
                assert (transform.header.frame_id, transform.child_frame_id) == (
                    MODEL_FRAME,
                    f"{DATA_FRAME}_scaled",
                )
                t = transform.transform.translation
                np.testing.assert_allclose([t.x, t.y, t.z], record["translation"], atol=1e-12)
            elif suffix == "similarity":
                matrix = np.asarray(msg.data).reshape(4, 4)
                estimate = Similarity.from_matrix(matrix)
                assert estimate.scale == pytest.approx(record["scale"], rel=1e-9)
            else:
                assert msg.header.frame_id == MODEL_FRAME
                source = next(r for r in scenario.records if r.bag_ns == stamp_ns)
                truth = scenario.truth[stamp_ns]
                aligned = cloud_to_points(msg, 3)
                # Aligned with the estimate ~ aligned with the truth, point by point.
                assert np.abs(aligned - truth.apply(source.points)).max() < 0.03 * truth.scale
        expected = sorted(records)
        assert {topic: sorted(stamps) for topic, stamps in seen.items()} == dict.fromkeys(
            reader.topics, expected
        )


def test_no_aligned_leaves_the_cloud_topic_out(capsys, bags, tmp_path):
    from rosbags.highlevel import AnyReader

    out_bag = tmp_path / "lean"
    code, _, err = run_cli(
        capsys,
        *bag_args(
            bags["rosbags-mcap"], "--out-bag", out_bag, "--no-aligned", "--out-prefix", "/robot/frisicp"
        ),
    )
    assert code == 0, err
    with AnyReader([out_bag]) as reader:
        assert sorted(reader.topics) == [
            "/robot/frisicp/pose",
            "/robot/frisicp/rms",
            "/robot/frisicp/scale",
            "/robot/frisicp/similarity",
            "/robot/frisicp/transform",
            "/tf",
        ]
        assert all(info.msgcount == 4 for info in reader.topics.values())


def test_bag_mode_never_imports_rclpy(bags, tmp_path):
    """Run with rclpy made unimportable, as on a machine without ROS."""
    script = (
        "import sys\n"
        "class NoRos:\n"
        "    def find_spec(self, name, path=None, target=None):\n"
        "        if name.split('.')[0] in ('rclpy', 'rosidl_runtime_py', 'sensor_msgs', 'geometry_msgs'):\n"
        "            raise ImportError('no ROS here: ' + name)\n"
        "sys.meta_path.insert(0, NoRos())\n"
        "from frisicp_ros.cli.main import main\n"
        f"code = main({bag_args(bags['foxglove-mcap-file'], '--out-bag', str(tmp_path / 'o'), '--no-warm-start', '--jobs', '2')!r})\n"
        "sys.exit(code)\n"
    )
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=90)
    assert done.returncode == 0, done.stderr
    assert len(read_jsonl(done.stdout)) == 4
    assert "Traceback" not in done.stderr


# --- bad input -----------------------------------------------------------------------------------


def assert_clean_failure(code: int, err: str, *fragments: str) -> None:
    assert code != 0
    assert "Traceback" not in err
    for fragment in fragments:
        assert fragment in err, err


def test_missing_topic_lists_the_pointcloud2_topics(capsys, bags):
    code, out, err = run_cli(
        capsys, "bag", bags["rosbags-sqlite3"], "--model-topic", MODEL_TOPIC, "--data-topic", "/points"
    )
    assert_clean_failure(
        code, err, "/points is not in the bag", f"PointCloud2 topics: {MODEL_TOPIC}, {DATA_TOPIC}"
    )
    assert out == ""


def test_wrong_type_is_named(capsys, bags):
    code, _, err = run_cli(
        capsys, "bag", bags["rosbags-sqlite3"], "--model-topic", MODEL_TOPIC, "--data-topic", OTHER_TOPIC
    )
    assert_clean_failure(
        code, err, f"{OTHER_TOPIC} carries std_msgs/msg/String, not sensor_msgs/msg/PointCloud2"
    )


@pytest.mark.parametrize(
    "problem",
    [
        "missing",
        "not-a-bag",
        "folder-without-metadata",
        "garbage-mcap",
        "empty-db3",
        "unreadable",
    ],
)
def test_unusable_bags_fail_with_one_clear_line(capsys, bags, tmp_path, problem):
    suffix = {"empty-db3": ".db3", "not-a-bag": ".txt"}.get(problem, ".mcap")
    path = tmp_path / f"input{suffix}"
    if problem == "folder-without-metadata":
        path = tmp_path / "folder"
        path.mkdir()
        (path / "folder.mcap").write_bytes(bags["foxglove-mcap-file"].read_bytes())
    elif problem == "garbage-mcap":
        path.write_bytes(np.random.default_rng(0).bytes(5000))
    elif problem in ("empty-db3", "not-a-bag"):
        path.write_bytes(b"")
    elif problem == "unreadable":
        path.write_bytes(bags["foxglove-mcap-file"].read_bytes())
        path.chmod(0)
        if os.access(path, os.R_OK):
            pytest.skip("running as root: file permissions do not apply")
    for command in (["bag-info", path], bag_args(path)):
        code, out, err = run_cli(capsys, *command)
        assert_clean_failure(code, err, str(path))
        assert err.count("\n") == 1, err
        assert out == ""
    if problem == "folder-without-metadata":
        assert "folder.mcap" in err  # says which file to open instead


def test_argument_mistakes_are_refused_before_reading(capsys, bags, tmp_path):
    bag = bags["rosbags-mcap"]
    code, _, err = run_cli(capsys, "bag", bag, "--model-topic", DATA_TOPIC, "--data-topic", DATA_TOPIC)
    assert_clean_failure(code, err, "must be different topics")
    code, _, err = run_cli(capsys, *bag_args(bag, "--jobs", "100000000"))
    assert_clean_failure(code, err, "--jobs must be in [1, ")
    code, _, err = run_cli(capsys, *bag_args(bag, "--levels", "100000000"))  # ran out of memory
    assert_clean_failure(code, err, "levels must be in [1, 10]")
    for flag in ("--max-iterations", "--coarsest-points", "--max-points", "--seed"):
        code, _, err = run_cli(capsys, *bag_args(bag, flag, "100000000000"))
        assert_clean_failure(code, err, f"{flag[2:].replace('-', '_')} must be in [")
    code, _, err = run_cli(capsys, *bag_args(bag, "--sync-tolerance", "0.2"))  # would be ignored
    assert_clean_failure(code, err, "--sync-tolerance applies only with --pairing synchronized")
    code, _, err = run_cli(capsys, *bag_args(bag, "--max-points", "-1"))
    assert_clean_failure(code, err, "max_points must be in [0, ")
    code, _, err = run_cli(capsys, *bag_args(bag, "--jobs", "0"))
    assert_clean_failure(code, err, "--jobs must be in [1, 256], got 0")
    code, _, err = run_cli(capsys, *bag_args(bag, "--overlap", "1.5"))
    assert_clean_failure(code, err, "overlap")
    existing = tmp_path / "exists"
    existing.mkdir()
    code, out, err = run_cli(capsys, *bag_args(bag, "--out-bag", existing, "--out", tmp_path / "never.jsonl"))
    assert_clean_failure(code, err, "exists already")
    assert out == "" and not (tmp_path / "never.jsonl").exists()


def write_bag_with_corrupt_message(path: Path, scenario: Scenario, corrupt_at: int) -> Path:
    """A rosbag2 whose ``corrupt_at``-th data message is cut short (bytes lost on disk)."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore
    from support.bags import rosbags_cloud

    typestore = get_typestore(Stores.ROS2_JAZZY)
    with Writer(path, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        connections = {
            topic: writer.add_connection(topic, "sensor_msgs/msg/PointCloud2", typestore=typestore)
            for topic in (MODEL_TOPIC, DATA_TOPIC)
        }
        data_seen = 0
        for record in scenario.records:
            raw = typestore.serialize_cdr(rosbags_cloud(typestore, record), "sensor_msgs/msg/PointCloud2")
            if record.topic == DATA_TOPIC:
                if data_seen == corrupt_at:
                    raw = raw[:100]
                data_seen += 1
            writer.write(connections[record.topic], record.bag_ns, raw)
    return path


def test_budget_seconds_bounds_each_registration(capsys, bags):
    code, out, err = run_cli(
        capsys, *bag_args(bags["rosbags-mcap"], "--no-progress", "--budget-seconds", "1e-9")
    )
    assert code == 0, err  # read to its end; each pair marked
    records = read_jsonl(out)
    assert len(records) == 4 and all(r["ok"] is False for r in records)
    assert all(r["reason"].startswith("budget exceeded: stopped after") for r in records)
    assert "pairs 4 (rejected 0, unreliable 4)" in err


def test_corrupt_message_mid_bag_keeps_earlier_results_and_says_where(capsys, scenario, tmp_path):
    bag = write_bag_with_corrupt_message(tmp_path / "corrupt", scenario, corrupt_at=2)
    out_bag = tmp_path / "partial_results"
    results = tmp_path / "results.jsonl"
    code, _, err = run_cli(capsys, *bag_args(bag, "--out", results, "--out-bag", out_bag))
    assert code == 1
    assert "Traceback" not in err
    bad = scenario.data_records()[2]
    assert "stopped after pair 1" in err and f"{DATA_TOPIC} at bag time {bad.bag_ns} ns" in err, err
    assert "cannot be decoded" in err and "2 results kept" in err
    records = read_jsonl(results.read_text())
    assert [r["stamp_ns"] for r in records] == [d.bag_ns for d in scenario.data_records()[:2]]
    from rosbags.highlevel import AnyReader

    with AnyReader([out_bag]) as reader:
        assert reader.topics["/frisicp/transform"].msgcount == 2


def test_damage_found_while_reading_keeps_earlier_results_and_says_where(capsys, scenario, tmp_path):
    """A flipped byte in a late chunk of an independently written MCAP (one message per chunk):
    the chunk's CRC fails only when the reading gets there."""
    bag = write_mcap_ros2(tmp_path / "damaged.mcap", scenario.records, chunk_size=1000)
    raw = bytearray(bag.read_bytes())
    at = int(len(raw) * 0.6)
    raw[at : at + 8] = bytes(byte ^ 0xA5 for byte in raw[at : at + 8])
    bag.write_bytes(raw)
    code, out, err = run_cli(capsys, *bag_args(bag, "--no-progress"))
    assert code == 1 and "Traceback" not in err
    assert "the bag is damaged after message" in err and "crc validation failed in Chunk" in err, err
    records = read_jsonl(out)
    assert 1 <= len(records) < 4 and f"{len(records)} results kept in stdout" in err
    for record in records:
        assert_matches_truth(record, scenario.truth[record["stamp_ns"]])


def test_malformed_cloud_is_reported_as_a_rejected_pair_and_the_run_goes_on(capsys, tmp_path):
    model = bumpy_surface(POINTS, seed=1)
    truth = truth_for(0)
    records = [
        CloudRecord(MODEL_TOPIC, 10, 10, MODEL_FRAME, model),
        CloudRecord(DATA_TOPIC, 20, 20, DATA_FRAME, np.full((POINTS, 3), np.nan)),
        CloudRecord(DATA_TOPIC, 30, 30, DATA_FRAME, data_cloud(model, truth, 0)),
    ]
    bag = write_rosbag2(tmp_path / "nan", records, "mcap")
    code, out, err = run_cli(capsys, *bag_args(bag))
    assert code == 0, err
    first, second = read_jsonl(out)
    assert first["ok"] is False and first["rejected_input"] == "data" and "finite" in first["rejection"]
    assert_matches_truth(second, truth)
    assert "pairs 2 (rejected 1, unreliable 0), converged 1" in err


def test_a_bag_without_pairs_says_why(capsys, tmp_path):
    model = bumpy_surface(200, seed=1)
    records = [
        CloudRecord(DATA_TOPIC, 10, 10, DATA_FRAME, model),
        CloudRecord(MODEL_TOPIC, 10**9, 10**9, MODEL_FRAME, model),
    ]
    bag = write_rosbag2(tmp_path / "late_model", records, "sqlite3")
    code, out, err = run_cli(capsys, *bag_args(bag))
    assert code == 0 and out == ""
    assert "pairs 0" in err and "every data cloud came before the first model cloud" in err
    code, out, err = run_cli(capsys, *bag_args(bag, "--pairing", "synchronized"))
    assert "no model and data header stamps within --sync-tolerance" in err


def test_a_closed_results_pipe_stops_cleanly_and_keeps_the_result_bag(bags, tmp_path):
    """`frisicp bag ... | head -0`: no BrokenPipeError traceback, the result bag is finished."""
    out_bag = tmp_path / "piped"
    command = [
        installed_script("frisicp"),
        *bag_args(bags["rosbags-mcap"], "--out-bag", str(out_bag), "--no-progress"),
    ]
    process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    process.stdout.close()  # the reader is gone before the first result (start-up takes longer)
    err = process.stderr.read()
    assert process.wait(timeout=60) == 1
    assert "closed the pipe" in err and "0 results kept" in err, err
    assert "Traceback" not in err and "Exception ignored" not in err, err
    from rosbags.highlevel import AnyReader

    with AnyReader([out_bag]) as reader:  # finished and readable, though empty
        assert reader.topics["/frisicp/transform"].msgcount == 0


def test_a_damaged_but_decodable_cloud_is_marked_unreliable_not_reported_as_a_pose(capsys, tmp_path):
    """Bytes damaged on disk inside a cloud's point data (no checksum notices): the message
    decodes, its numbers are garbage. It used to give a "converged" pose. Now its line says
    ok false with the reason, the summary counts it, the result bag leaves it out, and the pair
    after it is right (the damage did not poison the warm start)."""
    from rosbags.highlevel import AnyReader
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore
    from support.bags import rosbags_cloud

    model = bumpy_surface(POINTS, seed=1)
    truth = truth_for(0)
    records = [
        CloudRecord(MODEL_TOPIC, 10, 10, MODEL_FRAME, model),
        CloudRecord(DATA_TOPIC, 20, 20, DATA_FRAME, data_cloud(model, truth, 1)),
        CloudRecord(DATA_TOPIC, 30, 30, DATA_FRAME, data_cloud(model, truth, 2)),  # damaged below
        CloudRecord(DATA_TOPIC, 40, 40, DATA_FRAME, data_cloud(model, truth, 3)),
    ]
    typestore = get_typestore(Stores.ROS2_JAZZY)
    bag, out_bag = tmp_path / "damaged", tmp_path / "results"
    noise = np.random.default_rng(7)
    with Writer(bag, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        connections = {
            topic: writer.add_connection(topic, "sensor_msgs/msg/PointCloud2", typestore=typestore)
            for topic in (MODEL_TOPIC, DATA_TOPIC)
        }
        for record in records:
            raw = bytearray(
                typestore.serialize_cdr(rosbags_cloud(typestore, record), "sensor_msgs/msg/PointCloud2")
            )
            if record.bag_ns == 30:  # the point bytes (all but the last byte, is_dense) overwritten
                size = len(record.points) * 16
                raw[-size - 1 : -1] = noise.bytes(size)
            writer.write(connections[record.topic], record.bag_ns, bytes(raw))
    code, out, err = run_cli(capsys, *bag_args(bag, "--out-bag", out_bag, "--no-progress"))
    assert code == 0, err  # the bag was read to its end; the verdict is per pair
    good_before, damaged, good_after = read_jsonl(out)
    assert_matches_truth(good_before, truth)
    assert damaged["ok"] is False and damaged["reliable"] is False and damaged["reason"], damaged
    assert_matches_truth(good_after, truth)
    assert ("unreliable 1" in err) or ("rejected 1" in err), err
    with AnyReader([out_bag]) as reader:
        assert reader.topics["/frisicp/transform"].msgcount == 2


def test_plot_draws_the_bag_over_time(capsys, bags, tmp_path):
    from support.png import png_size

    picture = tmp_path / "over_time.png"
    code, _, err = run_cli(capsys, *bag_args(bags["rosbags-mcap"], "--plot", str(picture)))
    assert code == 0 and f"picture {picture}" in err, err
    width, height = png_size(picture)
    assert height > width > 400 and picture.stat().st_size < 200_000


def test_initial_guess_steers_the_first_pair_and_tracking_follows(capsys, tmp_path):
    """The symmetric scene of test_guess in a bag: blind, no pair is answered right and reliable;
    with --initial every pair is right, in every bag of a batch; refused where parallel chunks
    would start blind."""
    from support.bags import CloudRecord
    from support.guess_scene import right_and_reliable, symmetric_scene_clouds

    from frisicp_ros.stream.outputs import rosbags_message_types
    from frisicp_ros.stream.pointcloud2 import cloud_to_points

    model, data, truth, rough = symmetric_scene_clouds(rosbags_message_types())
    records = [CloudRecord(MODEL_TOPIC, 1, 1, MODEL_FRAME, cloud_to_points(model, 3))]
    for k, cloud in enumerate(data):
        stamp = stamp_ns_of(cloud.header)
        records.append(CloudRecord(DATA_TOPIC, 10 + k, stamp, DATA_FRAME, cloud_to_points(cloud, 3)))
    bag = write_rosbag2(tmp_path / "symmetric", records, storage="mcap")
    pose = " ".join(str(v) for v in [*rough.translation, *rough.quaternion()])

    code, out, err = run_cli(capsys, *bag_args(bag, "--max-points", "0"))
    assert code == 0, err
    for record in read_jsonl(out):
        error = rotation_angle_deg(np.array(record["rotation"]).T @ truth.rotation)
        assert not right_and_reliable(error, record["reliable"])
    # Two bags (the same recording): the guess steers the first pair of each, which starts cold
    # as if registered alone, so both get the same right lines.
    shutil.copytree(bag, tmp_path / "again")
    out = tmp_path / "out"
    code, _, err = run_cli(
        capsys,
        "bag",
        str(bag),
        str(tmp_path / "again"),
        *bag_args(bag)[2:],
        *("--out-dir", str(out), "--max-points", "0", "--no-progress"),
        *("--initial", pose, "--initial-sigma", "5,0.1"),
    )
    assert code == 0, err
    first, again = (read_jsonl((out / f"{name}.jsonl").read_text()) for name in ("symmetric", "again"))
    assert [r["rotation"] for r in first] == [r["rotation"] for r in again]
    assert all(r["reliable"] for r in first)
    assert all(rotation_angle_deg(np.array(r["rotation"]).T @ truth.rotation) < 0.5 for r in first)
    for parallel in (["--jobs", "2"], ["--scheduler", "tcp://127.0.0.1:1"]):
        code, _, err = run_cli(
            capsys, *bag_args(bag, "--initial", pose, "--initial-sigma", "5,0.1", *parallel)
        )
        assert code == 2 and "leave out --jobs N and --scheduler" in err, err
