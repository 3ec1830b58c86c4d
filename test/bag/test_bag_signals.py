"""`frisicp bag` under Ctrl-C and SIGTERM, as a terminal and a service manager send them.

The command runs in its own session and the signals go to its whole process group, as a
terminal's Ctrl-C does (the worker processes get them too). Whatever the sequence: the command
exits with 130 (SIGINT) or 143 (SIGTERM), prints no traceback, keeps every result written so far,
leaves a finished, readable result bag (never a ``DIR.partial-PID``) and no process behind.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import time
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
    one_model_then_data,
    truth_for,
    write_rosbag2,
)
from support.scripts import installed_script

from frisicp_core import bumpy_surface

FRISICP = installed_script("frisicp")
INT, TERM = signal.SIGINT, signal.SIGTERM
TOPICS = ("--model-topic", MODEL_TOPIC, "--data-topic", DATA_TOPIC)


@pytest.fixture(scope="module")
def long_bag(tmp_path_factory) -> Path:
    """200 pairs: far more than can finish before the signals."""
    records, _ = one_model_then_data(200, 3000)
    return write_rosbag2(tmp_path_factory.mktemp("signals") / "long", records, "mcap")


def run_and_signal(bag: Path, tmp_path: Path, jobs: str, signals: list[int], gap: float, *extra: str):
    results, out_bag = tmp_path / "results.jsonl", tmp_path / "out"
    command = [str(FRISICP), "bag", str(bag), *TOPICS, "--out", str(results), "--out-bag", str(out_bag)]
    command += ["--jobs", jobs, *extra]
    process = subprocess.Popen(command, stderr=subprocess.PIPE, text=True, start_new_session=True)
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline and (not results.exists() or results.read_text().count("\n") < 2):
        time.sleep(0.02)
    for signum in signals:
        os.killpg(process.pid, signum)  # the whole group, as a terminal does
        time.sleep(gap)
    try:
        _, err = process.communicate(timeout=30)
    except subprocess.TimeoutExpired:
        os.killpg(process.pid, signal.SIGKILL)
        process.communicate()
        pytest.fail(f"frisicp bag --jobs {jobs} hung after {signals}")
    return process, err, results, out_bag


def assert_group_gone(pgid: int) -> None:
    """No worker process outlives the command (a third Ctrl-C used to orphan them)."""
    deadline = time.monotonic() + 5
    while time.monotonic() < deadline:
        try:
            os.killpg(pgid, 0)
        except ProcessLookupError:
            return
        time.sleep(0.05)
    os.killpg(pgid, signal.SIGKILL)
    pytest.fail("processes of the command's group are still running after it exited")


@pytest.mark.parametrize(
    ("jobs", "signals", "code"),
    [
        ("1", [INT], 130),
        ("2", [INT], 130),  # ignored in 2 of 6 tries: it came while a chunk was submitted (test_jobs)
        ("1", [INT, INT], 130),  # used to exit -2 with a traceback
        ("2", [INT, INT], 130),  # used to hang joining idle workers (4 of 5 tries)
        ("2", [INT, INT, INT], 130),  # used to orphan the workers
        ("1", [TERM], 143),  # used to leave DIR.partial-PID without metadata
        ("2", [TERM, TERM, INT], 143),
    ],
    ids=["int-1", "int-2", "int-int-1", "int-int-2", "int-int-int-2", "term-1", "term-term-int-2"],
)
def test_signals_stop_cleanly_keep_every_result_and_finish_the_result_bag(
    long_bag, tmp_path, jobs, signals, code
):
    process, err, results, out_bag = run_and_signal(long_bag, tmp_path, jobs, signals, 0.05)
    assert process.returncode == code, err
    assert "Traceback" not in err, err
    assert ("terminated (SIGTERM)" if code == 143 else "interrupted") in err
    kept = [json.loads(line) for line in results.read_text().splitlines()]
    assert 2 <= len(kept) < 200
    assert [r["pair"] for r in kept] == list(range(len(kept)))
    assert f"{len(kept)} results kept" in err
    assert not list(tmp_path.glob("out.partial-*")), "the result bag was left unfinished"
    from rosbags.highlevel import AnyReader

    with AnyReader([out_bag]) as reader:
        assert reader.topics["/frisicp/transform"].msgcount == sum(r["ok"] for r in kept)
    assert_group_gone(process.pid)


def test_a_second_ctrl_c_abandons_a_long_registration_at_once(tmp_path):
    """The first Ctrl-C finishes the pair in hand; the second does not wait for it."""
    model = bumpy_surface(150_000, seed=1)
    records = [CloudRecord(MODEL_TOPIC, 10**9, 10**9, MODEL_FRAME, model)]
    # Several slow pairs, so that one is in hand when the signals come however fast the core is
    # (a single pair once finished before the first Ctrl-C).
    for k in range(6):
        noisy = data_cloud(model, truth_for(k), k) + np.random.default_rng(k).normal(0, 0.01, (120_000, 3))
        records.append(CloudRecord(DATA_TOPIC, (2 + k) * 10**9, (2 + k) * 10**9, DATA_FRAME, noisy))
    bag = write_rosbag2(tmp_path / "slow", records, "mcap")
    command = [str(FRISICP), "bag", str(bag), *TOPICS]
    # Full clouds with noise and no convergence threshold: registrations of seconds each.
    command += ["--max-points", "0", "--relative-motion", "0", "--relative-rmse", "0", "--no-noise-floor"]
    command += ["--no-progress", "--out", str(tmp_path / "r.jsonl")]
    process = subprocess.Popen(command, stderr=subprocess.PIPE, text=True, start_new_session=True)
    time.sleep(4.0)  # started, and inside the registration
    os.killpg(process.pid, INT)
    # Apart by more than one numerical step of the core: Python runs a signal handler between
    # two bytecodes, and signals arriving during one long C call are seen as one.
    time.sleep(0.5)
    os.killpg(process.pid, INT)
    sent = time.monotonic()
    _, err = process.communicate(timeout=30)
    assert process.returncode == 130 and "Traceback" not in err, err
    assert time.monotonic() - sent < 2.0, f"the second Ctrl-C waited for the registration: {err}"
