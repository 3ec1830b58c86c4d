"""Damaged bags and signal storms to ``frisicp bag``.

Bags: a recording of one model and ``PAIRS`` data clouds of known poses, in every format the bag
mode reads (written by the test suite's writers: rosbags, and Foxglove's mcap for an independent
MCAP), damaged at random: cut, bytes flipped, a range zeroed, garbage appended, emptied, its
metadata.yaml removed, a ROS 1 md5sum changed. Each run must exit 0, 1 or 2 without a traceback
or a hang; every line marked ``"ok": true`` must be the truth; the results said to be kept must be
in the file, as pairs 0, 1, 2, ... in order.

Signals: ``frisicp bag --jobs 1|2`` on a long recording gets 1-4 SIGINT/SIGTERM at random moments
(to its process group, as a terminal sends them). It must exit 130 or 143 by the first signal,
without a traceback, keep what it said it kept, leave a finished result bag and no process.
"""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
from common import BIN, Finished, Tally, judge_exit, run

from frisicp_core import Similarity, rotation_angle

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "test"))
from support.bags import (
    DATA_TOPIC,
    MODEL_TOPIC,
    one_model_then_data,
    write_mcap_ros2,
    write_ros1_bag,
    write_rosbag2,
)

PAIRS = 12
TOPICS = ["--model-topic", MODEL_TOPIC, "--data-topic", DATA_TOPIC]
KEPT = re.compile(r"(\d+) results kept")
POINTCLOUD2_MD5 = b"1158d486dd51d683ce2f1be655c3c181"


def originals(root: Path) -> tuple[dict[str, Path], dict[int, Similarity]]:
    """One recording in every format: a rosbag2 folder's storage file, or the bag file itself."""
    records, truth = one_model_then_data(PAIRS, 600)
    return {
        "rosbag2-sqlite3": write_rosbag2(root / "sqlite", records, "sqlite3"),
        "rosbag2-mcap": write_rosbag2(root / "mcap", records, "mcap"),
        "mcap-chunked": write_mcap_ros2(root / "chunked.mcap", records, chunk_size=8000),
        "ros1": write_ros1_bag(root / "recording.bag", records),
    }, truth


def storage_file(bag: Path) -> Path:
    return next(p for p in bag.iterdir() if p.suffix in (".db3", ".mcap")) if bag.is_dir() else bag


DAMAGES: dict[str, Callable[[bytes, np.random.Generator], bytes | None]] = {
    "cut": lambda raw, rng: raw[: int(len(raw) * rng.uniform(0.02, 0.99))],
    "bytes flipped": lambda raw, rng: _flipped(raw, rng),
    "range zeroed": lambda raw, rng: _zeroed(raw, rng),
    "garbage appended": lambda raw, rng: raw + rng.bytes(int(rng.integers(1, 5000))),
    "emptied": lambda raw, rng: b"",
    "md5sum changed": lambda raw, rng: _md5_changed(raw, rng),
}


def _flipped(raw: bytes, rng: np.random.Generator) -> bytes:
    damaged = bytearray(raw)
    for at in rng.integers(0, len(raw), size=int(rng.integers(1, 16))):
        damaged[at] ^= int(rng.integers(1, 256))
    return bytes(damaged)


def _zeroed(raw: bytes, rng: np.random.Generator) -> bytes:
    start = int(rng.integers(0, len(raw)))
    end = min(len(raw), start + int(rng.integers(1, 4096)))
    return raw[:start] + bytes(end - start) + raw[end:]


def _md5_changed(raw: bytes, rng: np.random.Generator) -> bytes | None:
    sums = [m.start() for m in re.finditer(re.escape(POINTCLOUD2_MD5), raw)]
    if not sums:
        return None  # not a ROS 1 bag
    at = int(rng.choice(sums))
    return raw[:at] + rng.bytes(16).hex().encode() + raw[at + 32 :]


def check_results(tally: Tally, what: str, out: str, err: str, truth: dict[int, Similarity]) -> None:
    lines = [json.loads(line) for line in out.splitlines() if line.strip()]
    if [line["pair"] for line in lines] != list(range(len(lines))):
        tally.problem(
            "lost_results", f"{what}: pairs out of order or missing: {[line['pair'] for line in lines]}"
        )
    said = KEPT.search(err)
    if said and int(said.group(1)) != len(lines):
        tally.problem("lost_results", f"{what}: said {said.group(1)} results kept, {len(lines)} in the file")
    for line in lines:
        if line["ok"] and not _is_truth(line, truth.get(line["stamp_ns"])):
            tally.problem("wrong_answers", f"{what}: pair {line['pair']} ok but not the truth")


def _is_truth(line: dict, truth: Similarity | None) -> bool:
    if truth is None:
        return False
    estimate = Similarity.from_quaternion(line["scale"], line["quaternion_xyzw"], line["translation"])
    return bool(
        abs(estimate.scale / truth.scale - 1) < 0.01
        and np.degrees(rotation_angle(estimate.rotation.T @ truth.rotation)) < 1.0
        and np.linalg.norm(estimate.translation - truth.translation) < 0.02 * truth.scale + 0.01
    )


def damaged_bags(root: Path, rng: np.random.Generator, count: int, deadline: float) -> Tally:
    tally = Tally("frisicp bag, damaged bags")
    bags, truth = originals(root / "originals")
    for name, bag in bags.items():  # the undamaged ones: every pair, right
        finished = run([BIN / "frisicp", "bag", bag, *TOPICS, "--no-progress"], timeout=120)
        if judge_exit(tally, finished, {0}, f"{name} intact"):
            check_results(tally, f"{name} intact", finished.out, finished.err, truth)
            if finished.out.count('"ok": true') != PAIRS:
                tally.problem("lost_results", f"{name} intact: not every pair ok")
    special = [("fifo", _fifo_bag), ("no metadata.yaml", _without_metadata)]
    for attempt in range(count):
        if time.monotonic() > deadline:
            break
        folder = root / f"damaged{attempt}"
        folder.mkdir(parents=True)
        if attempt < len(special):
            label, make = special[attempt]
            target = make(folder, bags)
        else:
            kind = str(rng.choice(list(bags)))
            damage = str(rng.choice(list(DAMAGES)))
            source = storage_file(bags[kind])
            damaged = DAMAGES[damage](source.read_bytes(), rng)
            if damaged is None:
                continue
            target = folder / source.name
            target.write_bytes(damaged)
            label = f"{kind} {damage}"
        finished = run([BIN / "frisicp", "bag", target, *TOPICS, "--no-progress"], timeout=120)
        if judge_exit(tally, finished, {0, 1, 2}, label):
            check_results(tally, label, finished.out, finished.err, truth)
    return tally


def _fifo_bag(folder: Path, bags: dict[str, Path]) -> Path:
    fifo = folder / "recording.mcap"
    os.mkfifo(fifo)
    return fifo


def _without_metadata(folder: Path, bags: dict[str, Path]) -> Path:
    source = bags["rosbag2-mcap"]
    target = folder / source.name
    target.mkdir()
    (target / storage_file(source).name).write_bytes(storage_file(source).read_bytes())
    return target


def _group_gone(pgid: int, within: float) -> bool:
    deadline = time.monotonic() + within
    while time.monotonic() < deadline:
        try:
            os.killpg(pgid, 0)
        except ProcessLookupError:
            return True
        time.sleep(0.05)
    return False


def signal_storms(root: Path, rng: np.random.Generator, count: int, deadline: float) -> Tally:
    tally = Tally("frisicp bag, signals")
    records, truth = one_model_then_data(150, 3000)
    bag = write_rosbag2(root / "long", records, "mcap")
    signals_sent = 0
    for attempt in range(count):
        if time.monotonic() > deadline:
            break
        jobs = str(rng.choice(["1", "2"]))
        storm = [int(rng.choice([signal.SIGINT, signal.SIGTERM])) for _ in range(int(rng.integers(1, 5)))]
        gaps = rng.uniform(0.0, 0.3, size=len(storm))
        results, out_bag = root / f"storm{attempt}.jsonl", root / f"storm{attempt}_bag"
        command = [
            BIN / "frisicp",
            "bag",
            bag,
            *TOPICS,
            "--jobs",
            jobs,
            "--out",
            results,
            "--out-bag",
            out_bag,
        ]
        process = subprocess.Popen(
            [str(c) for c in command], stderr=subprocess.PIPE, text=True, start_new_session=True
        )
        wait_for = int(rng.integers(0, 4))  # results before the storm (0: at once, while starting)
        start = time.monotonic()
        while time.monotonic() - start < 60 and process.poll() is None:
            if results.exists() and results.read_text().count("\n") >= wait_for:
                break
            time.sleep(0.005)
        for signum, gap in zip(storm, gaps, strict=True):
            os.killpg(process.pid, signum)
            signals_sent += 1
            time.sleep(gap)
        what = f"--jobs {jobs}, {[signal.Signals(s).name for s in storm]} after {wait_for} results"
        try:
            _, err = process.communicate(timeout=60)
            code: int | None = process.returncode
        except subprocess.TimeoutExpired:
            os.killpg(process.pid, signal.SIGKILL)
            _, err = process.communicate()
            code = None
        finished = Finished(code, "", err, 0.0)
        expected = 128 + storm[0]
        if not judge_exit(tally, finished, {expected, 0}, what):
            continue
        if code == 0:
            tally.problem("ignored_signals", f"{what}: ran on to its end, exit 0")
        check_results(tally, what, results.read_text() if results.exists() else "", err, truth)
        if list(root.glob(f"storm{attempt}_bag.partial-*")):
            tally.problem("lost_results", f"{what}: the result bag was left unfinished")
        if not _group_gone(process.pid, within=5.0):
            tally.problem("crashes", f"{what}: processes of its group outlived it by 5 s")
            os.killpg(process.pid, signal.SIGKILL)
    tally.notes["signals sent"] = signals_sent
    return tally
