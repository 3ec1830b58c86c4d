"""`frisicp bag --scheduler` on a real Dask cluster: a `dask scheduler` and two `dask worker`
processes on 127.0.0.1 (test/support/cluster.py), three bags of 24 pairs each.

- Every line is the truth and equal to a local `--jobs 2` run's, also when a worker running a
  task of the run is killed: its chunks run again on the other worker, no line missing or doubled.
- Ctrl-C keeps every line written, cancels the run's tasks on the cluster and leaves the cluster
  up: it still registers the next run.
- A bag the workers cannot read (hidden from them by a mount namespace) is reported for that bag;
  the other bags are registered; the exit code says so.
- A scheduler lost mid-run stops the run with every line written kept, and says why.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import time
from pathlib import Path

import pytest
from support.bags import (
    DATA_FRAME,
    DATA_TOPIC,
    MODEL_FRAME,
    MODEL_TOPIC,
    CloudRecord,
    assert_matches_truth,
    data_cloud,
    truth_for,
    write_mcap_ros2,
    write_rosbag2,
)
from support.cluster import LocalDaskCluster
from support.scripts import installed_script

from frisicp_core import bumpy_surface
from frisicp_ros.cli import main as cli

pytest.importorskip("distributed", reason="the cluster tests need Dask's distributed (the [dask] extra)")

FRISICP = installed_script("frisicp")  # beside the interpreter, or in a colcon install prefix
TOPICS = ["--model-topic", MODEL_TOPIC, "--data-topic", DATA_TOPIC]
PAIRS = 24  # per bag: three chunks of 8; 3000-point clouds take tens of ms per pair
POINTS = 3000
NAMES = ("alpha", "bravo", "charlie")
TASKS = "frisicp-bag-"  # the key prefix of the run's tasks on the cluster


@pytest.fixture(scope="module")
def recordings(tmp_path_factory):
    """Three bags (two rosbag2 folders and a bare MCAP) in ``bags/``; truth by (bag, data bag time)."""
    root = tmp_path_factory.mktemp("fleet") / "bags"
    root.mkdir()
    paths, truth = {}, {}
    for number, name in enumerate(NAMES):
        model = bumpy_surface(POINTS, seed=number + 1)
        records = [CloudRecord(MODEL_TOPIC, 10**9, 10**9, MODEL_FRAME, model)]
        for k in range(PAIRS):
            stamp = 2 * 10**9 + k * 10**8
            truth[name, stamp] = truth_for((k + number) % 5)
            records.append(
                CloudRecord(DATA_TOPIC, stamp, stamp, DATA_FRAME, data_cloud(model, truth[name, stamp], k))
            )
        paths[name] = (
            write_mcap_ros2(root / f"{name}.mcap", records)
            if name == "charlie"
            else write_rosbag2(root / name, records, "mcap" if name == "alpha" else "sqlite3")
        )
    return paths, truth


@pytest.fixture(scope="module")
def local_lines(recordings, tmp_path_factory):
    """The reference: the same bags with --jobs 2 on this machine."""
    paths, _ = recordings
    out = tmp_path_factory.mktemp("local")
    code = cli.main(
        ["bag", *map(str, paths.values()), *TOPICS, "--out-dir", str(out), "--jobs", "2", "--no-progress"]
    )
    assert code == 0
    return {name: lines(out / f"{name}.jsonl") for name in NAMES}


@pytest.fixture
def cluster(tmp_path):
    started = LocalDaskCluster(tmp_path / "cluster")
    started.workdir.mkdir()
    try:
        yield started.start(workers=2)
    finally:
        started.stop()
    assert not started.alive()


def lines(path: Path) -> list[dict]:
    """The JSON lines without the timing, which differs from run to run."""
    return [
        {k: v for k, v in json.loads(line).items() if k != "seconds"}
        for line in path.read_text().splitlines()
    ]


def start_run(paths, out: Path, scheduler: str, *extra: str) -> subprocess.Popen:
    command = [
        str(FRISICP),
        "bag",
        *map(str, paths),
        *TOPICS,
        "--out-dir",
        str(out),
        "--scheduler",
        scheduler,
    ]
    return subprocess.Popen(
        [*command, "--no-progress", *extra], stderr=subprocess.PIPE, text=True, start_new_session=True
    )


def wait_for_a_line(out: Path, process: subprocess.Popen) -> None:
    deadline = time.monotonic() + 60
    while not any(p.stat().st_size for p in out.glob("*.jsonl")):
        if process.poll() is not None or time.monotonic() > deadline:
            pytest.fail(f"no result line appeared: {process.communicate()[1]}")
        time.sleep(0.01)


def finish(process: subprocess.Popen) -> str:
    try:
        return process.communicate(timeout=60)[1]
    except subprocess.TimeoutExpired:
        os.killpg(process.pid, signal.SIGKILL)
        pytest.fail(f"frisicp bag hung: {process.communicate()[1]}")


def assert_true_and_local(out: Path, truth, local_lines, names=NAMES) -> None:
    for name in names:
        written = lines(out / f"{name}.jsonl")
        assert [r["pair"] for r in written] == list(range(PAIRS)), name  # none missing, none doubled
        for record in written:
            assert_matches_truth(record, truth[name, record["stamp_ns"]])
        assert written == local_lines[name], name


def test_three_bags_on_two_workers_give_the_local_lines_although_a_worker_is_killed(
    recordings, local_lines, cluster, tmp_path
):
    paths, truth = recordings
    out = tmp_path / "out"
    process = start_run(paths.values(), out, cluster.address, "--result-bags")
    wait_for_a_line(out, process)
    killed = cluster.kill_a_worker_running(TASKS)  # it held a task of this run when it died
    err = finish(process)
    assert process.returncode == 0, err
    assert cluster.alive() == [name for name in ("w0", "w1") if name != killed]
    assert "Traceback" not in err
    assert_true_and_local(out, truth, local_lines)
    from rosbags.highlevel import AnyReader

    for name in NAMES:
        with AnyReader([out / f"{name}_results"]) as reader:
            assert reader.topics["/frisicp/transform"].msgcount == PAIRS
    assert "the cluster had 2 workers at the start, 1 at the end" in err, err
    assert f"batch of 3 bags: 3 read to the end; pairs {3 * PAIRS} (rejected 0, unreliable 0)" in err


@pytest.mark.parametrize(
    ("signals", "code", "said"),
    [([signal.SIGINT], 130, "interrupted"), ([signal.SIGTERM, signal.SIGTERM], 143, "terminated (SIGTERM)")],
    ids=["ctrl-c", "sigterm-twice"],
)
def test_ctrl_c_keeps_every_line_cancels_the_runs_tasks_and_leaves_the_cluster_up(
    recordings, local_lines, cluster, tmp_path, signals, code, said
):
    """The second SIGTERM abandons the wait for the chunk in hand at once (frisicp_ros.bag.stop)."""
    paths, truth = recordings
    out = tmp_path / "out"
    process = start_run(paths.values(), out, cluster.address)
    wait_for_a_line(out, process)
    for signum in signals:  # to the command's group, as a terminal does: the cluster is not in it
        os.killpg(process.pid, signum)
        time.sleep(0.05)
    err = finish(process)
    assert process.returncode == code, err
    assert "Traceback" not in err and said in err, err
    kept = {name: lines(out / f"{name}.jsonl") for name in NAMES if (out / f"{name}.jsonl").exists()}
    assert 1 <= sum(map(len, kept.values())) < 3 * PAIRS
    for name, written in kept.items():
        assert [r["pair"] for r in written] == list(range(len(written)))
        assert written == local_lines[name][: len(written)]
        for record in written:
            assert_matches_truth(record, truth[name, record["stamp_ns"]])
    # The run's tasks are gone from the scheduler (one running when cancelled finishes first).
    deadline = time.monotonic() + 20
    while cluster.tasks(TASKS) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert cluster.tasks(TASKS) == []
    assert cluster.alive() == ["w0", "w1"]
    again = tmp_path / "again"
    process = start_run([paths["bravo"]], again, cluster.address)
    err = finish(process)
    assert process.returncode == 0, err
    assert lines(again / "bravo.jsonl") == local_lines["bravo"]


def hiding_mounts_work() -> bool:
    probe = subprocess.run(["unshare", "-m", "sh", "-c", "mount -t tmpfs tmpfs /mnt"], capture_output=True)
    return probe.returncode == 0


@pytest.mark.skipif(
    not hiding_mounts_work(), reason="needs unshare -m and mount (root) to hide a bag from workers"
)
def test_a_bag_the_workers_cannot_read_is_reported_and_the_others_are_registered(
    recordings, local_lines, tmp_path
):
    """The workers run in a mount namespace where the folder holding one bag is an empty tmpfs:
    the bag exists for the client only, as when a shared filesystem is not mounted on the workers."""
    paths, truth = recordings
    hidden = tmp_path / "not_shared"
    hidden.mkdir()
    unshared = hidden / "delta.mcap"
    unshared.write_bytes(paths["charlie"].read_bytes())
    wrapper = ["unshare", "-m", "sh", "-c", f'mount -t tmpfs tmpfs "{hidden}" && exec "$@"', "sh"]
    cluster = LocalDaskCluster(tmp_path / "cluster")
    cluster.workdir.mkdir()
    try:
        cluster.start(workers=2, wrapper=wrapper)
        out = tmp_path / "out"
        process = start_run([paths["alpha"], unshared, paths["bravo"]], out, cluster.address)
        err = finish(process)
    finally:
        cluster.stop()
    assert process.returncode == 1, err
    assert "Traceback" not in err
    assert "frisicp bag: delta: stopped before the first pair: on worker tcp://127.0.0.1:" in err, err
    assert f"{unshared}: cannot read it here: No such file or directory; 0 results kept" in err, err
    assert lines(out / "delta.jsonl") == []
    assert_true_and_local(out, truth, local_lines, names=("alpha", "bravo"))
    assert "batch of 3 bags: 2 read to the end, 1 stopped early (delta)" in err


def test_an_unreachable_scheduler_is_one_clear_error(capsys, recordings, tmp_path):
    from frisicp_ros.bag.cluster import ClusterError, DaskCluster

    with pytest.raises(ClusterError, match=r"cannot connect to the Dask scheduler at tcp://127.0.0.1:9"):
        DaskCluster("tcp://127.0.0.1:9", timeout=1.0)


def test_a_scheduler_lost_mid_run_stops_the_run_with_every_line_kept(
    recordings, local_lines, cluster, tmp_path, capsys
):
    """In process, to give the client a 2 s reconnection timeout (the command's is 10 s)."""
    import threading

    from frisicp_ros.bag.cluster import DaskCluster
    from frisicp_ros.bag.run import BagJob, BagRun, Destinations, register_batch
    from frisicp_ros.stream.settings import settings_from

    paths, _ = recordings
    out = tmp_path / "out"
    out.mkdir()
    runs = [
        BagRun(
            BagJob(paths[name], Destinations(str(out / f"{name}.jsonl")), name),
            settings_from({}),
            (MODEL_TOPIC, DATA_TOPIC),
        )
        for name in NAMES
    ]
    for run in runs:
        run.survey()

    def kill_the_scheduler_after_a_line() -> None:
        deadline = time.monotonic() + 60
        while not (out / "alpha.jsonl").exists() or not (out / "alpha.jsonl").stat().st_size:
            if time.monotonic() > deadline:
                return
            time.sleep(0.01)
        scheduler = cluster.processes[0]
        os.killpg(scheduler.pid, signal.SIGKILL)
        scheduler.wait()

    killer = threading.Thread(target=kill_the_scheduler_after_a_line)
    killer.start()
    code = register_batch(runs, DaskCluster(cluster.address, timeout=2.0), progress=False)
    killer.join()
    err = capsys.readouterr().err
    assert code == 1, err
    assert (
        "cancelled this run's tasks (the scheduler restarted or is gone)" in err and "Traceback" not in err
    ), err
    written = lines(out / "alpha.jsonl")
    assert 1 <= len(written) < PAIRS and written == local_lines["alpha"][: len(written)]
    assert "batch of 3 bags: 0 read to the end, 1 stopped early (alpha), 2 not started" in err, err
