"""A cluster worker rebuilds, from locators, exactly the pairs the client read and paired; a bag
that is not the client's (missing, another file at the path) is refused with the reason."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from support.bags import (
    DATA_FRAME,
    DATA_TOPIC,
    MODEL_FRAME,
    MODEL_TOPIC,
    CloudRecord,
    data_cloud,
    standard_scenario,
    truth_for,
    write_mcap_ros2,
    write_ros1_bag,
    write_rosbag2,
)

from frisicp_core import bumpy_surface
from frisicp_ros.bag.locate import BagSource, locate, read_pairs
from frisicp_ros.bag.pairs import BagPair, PairReading
from frisicp_ros.bag.reader import BagError, open_bag
from frisicp_ros.stream.settings import settings_from


def client_pairs(bag: Path, **settings) -> list[BagPair]:
    with open_bag(bag) as reader:
        return list(PairReading.paired_as(settings_from(settings), reader, MODEL_TOPIC, DATA_TOPIC))


def assert_same_pairs(rebuilt: list[BagPair], read: list[BagPair]) -> None:
    assert len(rebuilt) == len(read)
    for mine, theirs in zip(rebuilt, read, strict=True):
        assert mine.index == theirs.index
        for a, b in ((mine.model, theirs.model), (mine.data, theirs.data)):
            assert (a.bag_ns, a.ordinal, a.repeat) == (b.bag_ns, b.ordinal, b.repeat)
            assert a.cloud.header == b.cloud.header
            assert (a.cloud.width, a.cloud.point_step, a.cloud.fields) == (
                b.cloud.width,
                b.cloud.point_step,
                b.cloud.fields,
            )
            np.testing.assert_array_equal(a.cloud.data, b.cloud.data)


def rebuilt(bag: Path, pairs: list[BagPair], chunk: slice) -> list[BagPair]:
    source = BagSource.of(bag, MODEL_TOPIC, DATA_TOPIC)
    return read_pairs(source, [locate(pair, source) for pair in pairs[chunk]])


@pytest.mark.parametrize("kind", ["rosbag2-mcap", "rosbag2-sqlite3", "bare-mcap", "ros1", "cut-mcap"])
def test_a_worker_reads_back_the_pairs_the_client_read(tmp_path, kind):
    scenario = standard_scenario(300)
    writers = {
        "rosbag2-mcap": lambda: write_rosbag2(tmp_path / "b", scenario.records, "mcap"),
        "rosbag2-sqlite3": lambda: write_rosbag2(tmp_path / "b", scenario.records, "sqlite3"),
        "bare-mcap": lambda: write_mcap_ros2(tmp_path / "b.mcap", scenario.records),
        "ros1": lambda: write_ros1_bag(tmp_path / "b.bag", scenario.records),
        "cut-mcap": lambda: write_mcap_ros2(tmp_path / "b.mcap", scenario.records, chunk_size=1000),
    }
    bag = writers[kind]()
    if kind == "cut-mcap":  # a salvaged bag: no index, read from the start
        bag.write_bytes(bag.read_bytes()[: int(bag.stat().st_size * 0.8)])
    pairs = client_pairs(bag)
    assert len(pairs) >= 2
    assert_same_pairs(rebuilt(bag, pairs, slice(1, None)), pairs[1:])  # a chunk from the middle


def test_clouds_recorded_at_the_same_bag_time_are_told_apart(tmp_path):
    """Three data clouds logged at the same bag time, one model: the repeat number finds each."""
    model = bumpy_surface(200, seed=1)
    records = [CloudRecord(MODEL_TOPIC, 10, 10, MODEL_FRAME, model)]
    records += [
        CloudRecord(DATA_TOPIC, 20, 15 + k, DATA_FRAME, data_cloud(model, truth_for(k), k)) for k in range(3)
    ]
    bag = write_rosbag2(tmp_path / "same_time", records, "mcap")
    pairs = client_pairs(bag)
    assert [p.data.repeat for p in pairs] == [0, 1, 2]
    assert_same_pairs(rebuilt(bag, pairs, slice(2, 3)), pairs[2:3])


def test_a_bag_that_is_not_the_clients_is_refused(tmp_path):
    scenario = standard_scenario(300)
    bag = write_mcap_ros2(tmp_path / "b.mcap", scenario.records)
    source = BagSource.of(bag, MODEL_TOPIC, DATA_TOPIC)
    locators = [locate(pair, source) for pair in client_pairs(bag)]
    other = standard_scenario(301)  # another recording at the same path
    write_mcap_ros2(bag, other.records)
    with pytest.raises(BagError, match="not the same bag"):
        read_pairs(source, locators)
    bag.unlink()
    with pytest.raises(BagError, match=f"{bag}: cannot read it here: No such file"):
        read_pairs(source, locators)
