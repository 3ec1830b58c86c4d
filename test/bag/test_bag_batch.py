"""`frisicp bag` over several bags on this machine: one JSONL (and result bag) per bag in --out-dir,
the lines of each bag those of a run of that bag alone, a bag that cannot be read reported while
the batch goes on, and the exit code saying so."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from support.bags import (
    DATA_TOPIC,
    MODEL_TOPIC,
    assert_matches_truth,
    standard_scenario,
    write_mcap_ros2,
    write_rosbag2,
)

from frisicp_ros.cli import main as cli

TOPICS = ["--model-topic", MODEL_TOPIC, "--data-topic", DATA_TOPIC]


@pytest.fixture(scope="module")
def scenario():
    return standard_scenario(600)


@pytest.fixture(scope="module")
def bags(tmp_path_factory, scenario) -> dict[str, Path]:
    root = tmp_path_factory.mktemp("batch")
    return {
        "folder_mcap": write_rosbag2(root / "folder_mcap", scenario.records, "mcap"),
        "folder_sqlite": write_rosbag2(root / "folder_sqlite", scenario.records, "sqlite3"),
        "bare": write_mcap_ros2(root / "bare.mcap", scenario.records),
    }


def run(capsys, *argv) -> tuple[int, str, str]:
    code = cli.main(["bag", *map(str, argv), *TOPICS])
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def lines(path: Path) -> list[dict]:
    """The JSON lines without the timing, which differs from run to run."""
    return [
        {k: v for k, v in json.loads(line).items() if k != "seconds"}
        for line in path.read_text().splitlines()
    ]


def test_each_bag_gets_its_own_jsonl_and_result_bag_with_the_lines_of_a_run_of_it_alone(
    capsys, bags, scenario, tmp_path
):
    from rosbags.highlevel import AnyReader

    out = tmp_path / "out"
    code, stdout, err = run(capsys, *bags.values(), "--out-dir", out, "--result-bags", "--jobs", "2")
    assert code == 0, err
    assert stdout == ""
    assert sorted(p.name for p in out.iterdir()) == sorted(
        [f"{name}.jsonl" for name in bags] + [f"{name}_results" for name in bags]
    )
    for name, bag in bags.items():
        alone = tmp_path / f"{name}_alone.jsonl"
        assert run(capsys, bag, "--out", alone, "--jobs", "2", "--no-progress")[0] == 0
        assert lines(out / f"{name}.jsonl") == lines(alone)
        assert len(lines(alone)) == 4
        for record in lines(alone):
            assert_matches_truth(record, scenario.truth[record["stamp_ns"]])
        with AnyReader([out / f"{name}_results"]) as reader:
            assert reader.topics["/frisicp/transform"].msgcount == 4
        assert f"frisicp bag: {name}: pairs 4 (rejected 0, unreliable 0), converged 4" in err
    assert "batch of 3 bags: 3 read to the end; pairs 12 (rejected 0, unreliable 0), converged 12" in err
    assert "12/12" in err  # one progress bar across the batch, in data clouds


def test_plots_draw_each_bag_over_time_beside_its_results(capsys, bags, tmp_path):
    from support.png import png_size

    out = tmp_path / "out"
    code, _, err = run(
        capsys, bags["bare"], bags["folder_mcap"], "--out-dir", out, "--plots", "--no-progress"
    )
    assert code == 0, err
    for name in ("bare", "folder_mcap"):
        assert f"frisicp bag: {name}: picture {out / name}.png" in err, err
        width, height = png_size(out / f"{name}.png")
        assert height > width > 400


def test_warm_start_starts_again_cold_with_every_bag(capsys, bags, tmp_path):
    """--jobs 1 warm-starts each pair from the one before, but never across two bags."""
    out = tmp_path / "out"
    code, _, err = run(capsys, bags["bare"], bags["folder_mcap"], "--out-dir", out, "--no-progress")
    assert code == 0, err
    first, then = lines(out / "bare.jsonl"), lines(out / "folder_mcap.jsonl")
    assert first == then  # the same recording: the same lines, its first pair cold again
    assert [r["warm_started"] for r in then] == [False, True, True, True]


def test_an_unreadable_or_damaged_bag_is_reported_and_the_batch_goes_on(capsys, bags, scenario, tmp_path):
    cut = tmp_path / "cut.mcap"
    whole = write_mcap_ros2(tmp_path / "whole.mcap", scenario.records, chunk_size=1000)
    cut.write_bytes(whole.read_bytes()[: int(whole.stat().st_size * 0.7)])
    missing = tmp_path / "missing.mcap"
    out = tmp_path / "out"
    code, _, err = run(
        capsys, bags["folder_mcap"], missing, cut, bags["bare"], "--out-dir", out, "--no-progress"
    )
    assert code == 1, err
    assert "Traceback" not in err
    assert f"frisicp bag: missing: skipped: {missing}: no such file or directory" in err
    assert "frisicp bag: cut: stopped after pair" in err and "the bag is damaged" in err, err
    assert not (out / "missing.jsonl").exists()
    assert 1 <= len(lines(out / "cut.jsonl")) < 4
    for name in ("folder_mcap", "bare", "cut"):
        for record in lines(out / f"{name}.jsonl"):
            assert_matches_truth(record, scenario.truth[record["stamp_ns"]])
    assert len(lines(out / "bare.jsonl")) == 4
    assert "batch of 4 bags: 2 read to the end, 1 stopped early (cut), 1 unreadable (missing)" in err


def test_a_batch_with_no_readable_bag_exits_2(capsys, tmp_path):
    code, _, err = run(capsys, tmp_path / "a.mcap", tmp_path / "b.mcap", "--out-dir", tmp_path / "out")
    assert code == 2
    assert "a: skipped" in err and "b: skipped" in err and "0 read to the end, 2 unreadable (a, b)" in err


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        ([], "2 bags need --out-dir DIR"),
        (["--out-dir", "{tmp}/o", "--out", "{tmp}/x.jsonl"], "leave out --out, --out-bag and --plot"),
        (
            ["--out-dir", "{tmp}/o", "--plot", "{tmp}/x.png"],
            "--plots give a result bag and a picture per bag",
        ),
        (["--result-bags"], "--result-bags applies only with --out-dir"),
        (["--plots"], "--plots applies only with --out-dir"),
        (
            ["--out-dir", "{tmp}/o", "--jobs", "2", "--scheduler", "tcp://127.0.0.1:1"],
            "--jobs is for this machine",
        ),
    ],
)
def test_batch_arguments_are_checked_before_any_work(capsys, bags, tmp_path, extra, message):
    extra = [e.replace("{tmp}", str(tmp_path)) for e in extra]
    code, _, err = run(capsys, bags["bare"], bags["folder_mcap"], *extra)
    assert code == 2 and message in err, err
    assert not (tmp_path / "o").exists()


def test_bags_whose_results_would_share_a_name_are_refused(capsys, bags, tmp_path):
    other = tmp_path / "elsewhere"
    other.mkdir()
    (other / "bare.mcap").write_bytes(bags["bare"].read_bytes())
    code, _, err = run(capsys, bags["bare"], other / "bare.mcap", "--out-dir", tmp_path / "o")
    assert code == 2 and f"would both write {tmp_path / 'o' / 'bare'}.jsonl" in err, err
    existing = tmp_path / "o2" / "bare_results"
    existing.mkdir(parents=True)
    code, _, err = run(capsys, bags["bare"], "--out-dir", tmp_path / "o2", "--result-bags")
    assert code == 2 and f"{existing} exists already" in err, err
