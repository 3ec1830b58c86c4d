"""Bags cut off part-way (a crash or a full disk while recording, a partial copy): every format
is read up to the cut, every pair before it is registered and kept, and the damage is reported.

rosbags itself refuses these files at open (no MCAP footer, no ROS 1 index, SQLite pages
missing); they used to give 0 results although most pairs lie before the cut.
"""

from __future__ import annotations

import json

import pytest
from support.bags import (
    DATA_TOPIC,
    MODEL_TOPIC,
    assert_matches_truth,
    one_model_then_data,
    write_mcap_ros2,
    write_ros1_bag,
    write_rosbag2,
)

from frisicp_ros.cli import main as cli

PAIRS = 20


@pytest.fixture(scope="module")
def recordings(tmp_path_factory):
    """One model, then 20 data clouds, in every format; truth by data bag time."""
    root = tmp_path_factory.mktemp("damaged")
    records, truth = one_model_then_data(PAIRS, 600)
    files = {
        "rosbag2-sqlite3": write_rosbag2(root / "sqlite", records, "sqlite3") / "sqlite.db3",
        "rosbag2-mcap": write_rosbag2(root / "mcap", records, "mcap") / "mcap.mcap",
        "mcap-chunked": write_mcap_ros2(root / "chunked.mcap", records, chunk_size=20000),
        "ros1": write_ros1_bag(root / "recording.bag", records),
    }
    return files, truth


def cut(source, fraction: float, target):
    target.write_bytes(source.read_bytes()[: int(source.stat().st_size * fraction)])
    return target


@pytest.mark.parametrize("kind", ["rosbag2-sqlite3", "rosbag2-mcap", "mcap-chunked", "ros1"])
def test_a_bag_cut_at_90_percent_keeps_every_pair_before_the_cut(capsys, recordings, tmp_path, kind):
    files, truth = recordings
    source = files[kind]
    bag = cut(source, 0.9, tmp_path / source.name)
    code = cli.main(
        ["bag", str(bag), "--model-topic", MODEL_TOPIC, "--data-topic", DATA_TOPIC, "--no-progress"]
    )
    captured = capsys.readouterr()
    assert code == 1, captured.err  # results, but not the whole bag
    assert "Traceback" not in captured.err
    assert "the bag is damaged" in captured.err and "results kept" in captured.err, captured.err
    records = [json.loads(line) for line in captured.out.splitlines()]
    assert len(records) >= PAIRS * 3 // 4, f"only {len(records)} of {PAIRS} pairs read before the cut"
    assert [r["pair"] for r in records] == list(range(len(records)))
    for record in records:
        assert_matches_truth(record, truth[record["stamp_ns"]])


def test_a_rosbag2_folder_whose_storage_file_was_cut_is_read_too(capsys, recordings, tmp_path):
    files, _ = recordings
    folder = tmp_path / "mcap"
    folder.mkdir()
    (folder / "metadata.yaml").write_bytes((files["rosbag2-mcap"].parent / "metadata.yaml").read_bytes())
    cut(files["rosbag2-mcap"], 0.9, folder / "mcap.mcap")
    code = cli.main(
        ["bag", str(folder), "--model-topic", MODEL_TOPIC, "--data-topic", DATA_TOPIC, "--no-progress"]
    )
    captured = capsys.readouterr()
    assert code == 1 and "the bag is damaged" in captured.err, captured.err
    assert len(captured.out.splitlines()) >= PAIRS * 3 // 4


def test_bag_info_counts_what_can_be_read_and_says_the_bag_is_damaged(capsys, recordings, tmp_path):
    files, _ = recordings
    bag = cut(files["ros1"], 0.9, tmp_path / "recording.bag")
    code = cli.main(["bag-info", "--json", str(bag)])
    captured = capsys.readouterr()
    assert code == 1
    info = json.loads(captured.out)
    counts = {topic["name"]: topic["count"] for topic in info["topics"]}
    assert counts[MODEL_TOPIC] == 1 and PAIRS * 3 // 4 <= counts[DATA_TOPIC] < PAIRS
    assert "damaged" in info["damage"]


def test_a_file_with_nothing_readable_is_still_refused_with_the_reason(capsys, recordings, tmp_path):
    files, _ = recordings
    bag = cut(files["mcap-chunked"], 0.02, tmp_path / "stub.mcap")  # the header, hardly more
    code = cli.main(["bag-info", str(bag)])
    captured = capsys.readouterr()
    assert code == 2 and "cannot open the bag" in captured.err and str(bag) in captured.err


def whole_rows_before(raw: bytes, blobs: list[bytes], pages: int, page_size: int) -> int:
    """Messages whose every byte lies in the first ``pages`` pages: the page of the blob's start
    (its row's cell) and of its end (the last overflow page), found by content."""
    spans = [(raw.find(b[:64]) // page_size, (raw.find(b[-64:]) + 63) // page_size) for b in blobs]
    return sum(max(span) < pages for span in spans)


def test_a_sqlite_bag_cut_anywhere_keeps_every_message_that_lies_before_the_cut(recordings, tmp_path):
    """Python's sqlite3 cursor steps to the next row before returning one and drops it when that
    step fails: the salvage kept one message fewer than lay before the cut, at every cut, and a
    cut inside the first pages raised sqlite3.DatabaseError out of it."""
    import sqlite3

    from frisicp_ros.bag.salvage import salvage

    source = recordings[0]["rosbag2-sqlite3"]
    raw = source.read_bytes()
    page_size = int.from_bytes(raw[16:18], "big")
    with sqlite3.connect(source) as database:
        blobs = [bytes(row[0]) for row in database.execute("SELECT data FROM messages ORDER BY id")]
    checked = 0
    for pages in range(1, len(raw) // page_size):
        bag = tmp_path / "cut.db3"
        bag.write_bytes(raw[: pages * page_size])
        salvaged = salvage(bag)
        expected = whole_rows_before(raw, blobs, pages, page_size)
        assert (salvaged.message_count if salvaged else 0) == expected, f"cut after page {pages}"
        checked += expected > 0
    assert checked > 20
