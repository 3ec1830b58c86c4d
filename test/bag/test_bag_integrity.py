"""What a bag's own checks say is believed, and what they refuse is said (issue 17 item 4, 6):
the CRC of an MCAP's data section, a ROS 1 connection's md5sum, an empty bag, a FIFO; and the
reader of intact bags does without the salvage module (and its rosbags internals)."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys

import pytest
from support.bags import (
    DATA_TOPIC,
    MODEL_TOPIC,
    rosbags_cloud,
    standard_scenario,
    write_mcap_unchunked,
    write_ros1_bag,
    write_rosbag2,
)
from support.scripts import installed_script

from frisicp_ros.cli import main as cli

POINTCLOUD2_MD5 = b"1158d486dd51d683ce2f1be655c3c181"  # ROS 1 sensor_msgs/PointCloud2


@pytest.fixture(scope="module")
def scenario():
    return standard_scenario(600)


def rosbags_cdr(typestore, record) -> bytes:
    return bytes(typestore.serialize_cdr(rosbags_cloud(typestore, record), "sensor_msgs/msg/PointCloud2"))


def run(capsys, *argv) -> tuple[int, str, str]:
    code = cli.main([str(a) for a in argv])
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def bag_command(bag, *extra) -> list:
    return ["bag", bag, "--model-topic", MODEL_TOPIC, "--data-topic", DATA_TOPIC, "--no-progress", *extra]


def test_bytes_flipped_under_an_mcap_data_section_crc_are_reported_as_damage(capsys, scenario, tmp_path):
    """Messages outside chunks are covered only by the data section's CRC, which rosbags does
    not check: flipped point bytes went through and the run exited 0."""
    bag = write_mcap_unchunked(tmp_path / "unchunked.mcap", scenario.records)
    code, out, err = run(capsys, *bag_command(bag))
    assert code == 0 and len(out.splitlines()) == 4, err  # intact: every pair, no damage
    raw = bytearray(bag.read_bytes())
    at = int(len(raw) * 0.7)  # inside the point bytes of a late data cloud
    raw[at : at + 4] = bytes(byte ^ 0xA5 for byte in raw[at : at + 4])
    bag.write_bytes(raw)
    code, out, err = run(capsys, *bag_command(bag))
    assert code == 1 and "Traceback" not in err, err
    assert "the bag is damaged" in err and "crc validation failed in DataEnd" in err, err
    assert f"{len(out.splitlines())} results kept in stdout" in err


WRONG_MD5_SAID = {
    # rosbags keeps one md5sum per type, the last connection's: a wrong one on the model's
    # connection (in the index, where rosbags reads connections) was accepted silently.
    "model topic": (
        f"topic {MODEL_TOPIC}: its ROS 1 connection declares md5sum {'0' * 32}, but"
        f" sensor_msgs/PointCloud2 has {POINTCLOUD2_MD5.decode()}",
    ),
    # rosbags >= 0.11.x refuses the data topic's at open, and the salvage then read the whole file
    # as if it were cut ("the file ends ... before the bag's index", exit 1, every pair): now
    # rosbags' reason stands. Older rosbags open it, and the check above speaks.
    "data topic": (
        f"hash mismatch {POINTCLOUD2_MD5.decode()} != {'0' * 32}",
        f"topic {DATA_TOPIC}: its ROS 1 connection declares md5sum {'0' * 32}, but",
    ),
}


@pytest.mark.parametrize("which", list(WRONG_MD5_SAID))
def test_a_ros1_connection_with_a_wrong_md5sum_is_refused_with_both_sums(capsys, scenario, tmp_path, which):
    bag = write_ros1_bag(tmp_path / "recording.bag", scenario.records)
    raw = bag.read_bytes()
    sums = [match.start() for match in re.finditer(re.escape(POINTCLOUD2_MD5), raw)]
    assert len(sums) == 4  # each topic's connection: in its first chunk and in the index
    at = sums[2] if which == "model topic" else sums[3]
    bag.write_bytes(raw[:at] + b"0" * 32 + raw[at + 32 :])
    code, out, err = run(capsys, *bag_command(bag))
    assert code == 2 and out == "" and err.count("\n") == 1, err
    assert any(said in err for said in WRONG_MD5_SAID[which]), err


def test_an_empty_bag_exits_2_as_documented(capsys, scenario, tmp_path):
    """A bag with its topics but no message exited 0 ("pairs 0"); docs/bag.md says 2."""
    from rosbags.rosbag2 import Writer
    from rosbags.typesys import Stores, get_typestore

    bag = tmp_path / "empty"
    with Writer(bag, version=9) as writer:
        for topic in (MODEL_TOPIC, DATA_TOPIC):
            writer.add_connection(
                topic, "sensor_msgs/msg/PointCloud2", typestore=get_typestore(Stores.ROS2_JAZZY)
            )
    for command in (bag_command(bag), ["bag-info", bag]):
        code, out, err = run(capsys, *command)
        assert (
            code == 2
            and out == ""
            and err == f"frisicp {command[0]}: error: {bag}: the bag holds no messages\n"
        )


def test_a_topic_without_messages_is_refused(capsys, scenario, tmp_path):
    """Declared but never written: nothing to register ("pairs 0", exit 0, before)."""
    from rosbags.rosbag2 import Writer
    from rosbags.typesys import Stores, get_typestore

    typestore = get_typestore(Stores.ROS2_JAZZY)
    bag = tmp_path / "models_only"
    with Writer(bag, version=9) as writer:
        model = writer.add_connection(MODEL_TOPIC, "sensor_msgs/msg/PointCloud2", typestore=typestore)
        writer.add_connection(DATA_TOPIC, "sensor_msgs/msg/PointCloud2", typestore=typestore)
        first = scenario.records[0]
        writer.write(model, first.bag_ns, rosbags_cdr(typestore, first))
    code, out, err = run(capsys, *bag_command(bag))
    assert code == 2 and out == "" and f"topic {DATA_TOPIC} has no messages in the bag" in err, err


def test_a_fifo_is_refused_instead_of_waited_on(tmp_path):
    """Opening a FIFO waits for a writer: `frisicp bag-info a.mcap` on one never returned."""
    fifo = tmp_path / "recording.mcap"
    os.mkfifo(fifo)
    frisicp = installed_script("frisicp")  # beside the interpreter, or where colcon installs it
    for command in (bag_command(fifo), ["bag-info", fifo]):
        done = subprocess.run([frisicp, *map(str, command)], capture_output=True, text=True, timeout=60)
        assert done.returncode == 2 and "not a regular file (a FIFO, socket or device)" in done.stderr


def test_reading_an_intact_bag_never_imports_the_salvage(scenario, tmp_path):
    """bag/reader.py imported salvage (and through it rosbags names that exist only from 0.11.6)
    at load: frisicp bag, bag-info and the node's replay failed to import on rosbags 0.10-0.11.5."""
    bag = write_rosbag2(tmp_path / "intact", scenario.records, "mcap")
    script = (
        "import sys, json\n"
        "from frisicp_ros.cli import main\n"
        f"code = main.main(['bag-info', '--json', {str(bag)!r}])\n"
        "print(json.dumps({'code': code, 'salvage': 'frisicp_ros.bag.salvage' in sys.modules}))\n"
    )
    done = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, timeout=60, check=True
    )
    last = json.loads(done.stdout.splitlines()[-1])
    assert last == {"code": 0, "salvage": False}
