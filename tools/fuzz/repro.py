"""The measurements behind issue 17's fixes, each a small reproduction that prints its figures.

    python tools/fuzz/repro.py units        # clouds in units 10^a and 10^b: registered / refused / crashed
    python tools/fuzz/repro.py byte-order   # seconds until register answers for clouds read in the wrong byte order
    python tools/fuzz/repro.py ctrl-c       # one SIGINT to `frisicp bag --jobs 2` after its first result

The real data of ../shared/data (or $FRISICP_DATA) is read. For the figures of the code before a
fix, run the same command with ``PYTHONPATH`` pointing at a checkout of it (the commands it starts
inherit the variable too).
"""

from __future__ import annotations

import argparse
import os
import signal
import subprocess
import sys
import time
import warnings
from collections import Counter
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
DATA = Path(os.environ.get("FRISICP_DATA") or ROOT.parent / "shared" / "data")
EXPONENTS = (-300, -200, -150, -100, -50, -10, 0, 10, 50, 80, 100, 140, 150, 151, 200, 300)


def units() -> None:
    """bun_zipper_res2 x 10^a against a turned, scaled copy x 10^b, for 16 x 16 exponent pairs."""
    import frisicp_core
    from frisicp_core import Similarity, axis_angle_rotation, register
    from frisicp_core.io import read_points

    print(f"frisicp_core from {Path(frisicp_core.__file__).parent}")
    shape = read_points(DATA / "bunny" / "bun_zipper_res2.ply")
    turn = Similarity(1.5, axis_angle_rotation((0, 0, 1), 0.5), np.array([0.02, 0.0, 0.0]))
    outcomes: Counter[str] = Counter()
    warnings.simplefilter("ignore")
    for a in EXPONENTS:
        for b in EXPONENTS:
            try:
                result = register(shape * 10.0**a, turn.apply(shape) * 10.0**b)
                expected = 1.5 * 10.0 ** (b - a)
                right = result.reliable and abs(result.similarity.scale / expected - 1) < 1e-3
                outcomes["registered (scale within 1e-3)" if right else "wrong or unreliable"] += 1
            except ValueError as err:
                outcomes[f"refused: {str(err).split(':')[1].strip()[:40]}..."] += 1
            except Exception as err:  # noqa: BLE001 - what is being counted
                outcomes[f"crashed: {type(err).__name__}"] += 1
    for outcome, count in sorted(outcomes.items(), key=lambda item: -item[1]):
        print(f"{count:4d}  {outcome}")


def byte_order() -> None:
    """Each cloud's float32 bytes read with the other byte order (a lying is_bigendian), against
    the cloud itself: how long register takes to answer, and what it answers."""
    from frisicp_core import register
    from frisicp_core.io import read_points

    warnings.simplefilter("ignore")
    for name in ("bunny/bun000.ply", "bunny/bun_zipper.ply", "real/cturtle.pcd", "real/rs1.pcd"):
        points = read_points(DATA / name)
        points = points[np.isfinite(points).all(axis=1)]
        with np.errstate(invalid="ignore"):
            swapped = points.astype("<f4").view(">f4").astype(np.float64)
        swapped = swapped[np.isfinite(swapped).all(axis=1)]
        started = time.perf_counter()
        try:
            result = register(swapped, points)
            said = f"reliable={result.reliable}"
        except ValueError as err:
            said = f"refused ({str(err)[:60]}...)"
        print(f"{name}: {len(swapped)} points, {time.perf_counter() - started:.2f} s, {said}")


def ctrl_c(tries: int) -> None:
    """A 200-pair bag; one SIGINT to the process group right after the first result line."""
    sys.path.insert(0, str(ROOT / "test"))
    from support.bags import DATA_TOPIC, MODEL_TOPIC, one_model_then_data, write_rosbag2

    folder = ROOT / "build" / "repro-ctrl-c"
    bag = folder / "long"
    if not bag.exists():
        records, _ = one_model_then_data(200, 3000)
        write_rosbag2(bag, records, "mcap")
    frisicp = Path(sys.executable).parent / "frisicp"
    ignored = 0
    for attempt in range(tries):
        results = folder / f"results{attempt}.jsonl"
        results.unlink(missing_ok=True)
        command = [frisicp, "bag", bag, "--model-topic", MODEL_TOPIC, "--data-topic", DATA_TOPIC]
        command += ["--jobs", "2", "--out", results, "--no-progress"]
        process = subprocess.Popen(
            [str(c) for c in command], stderr=subprocess.DEVNULL, start_new_session=True
        )
        while not results.exists() or results.read_text().count("\n") < 1:
            time.sleep(0.005)
        os.killpg(process.pid, signal.SIGINT)
        code = process.wait(timeout=300)
        lines = results.read_text().count("\n")
        ignored += code == 0
        print(f"try {attempt}: exit {code}, {lines} results")
    print(f"the Ctrl-C was ignored (the run went on to its end) in {ignored} of {tries} tries")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("what", choices=("units", "byte-order", "ctrl-c"))
    parser.add_argument("--tries", type=int, default=8, help="ctrl-c: runs (default 8)")
    args = parser.parse_args()
    os.nice(19 - os.nice(0))
    {"units": units, "byte-order": byte_order, "ctrl-c": lambda: ctrl_c(args.tries)}[args.what]()


if __name__ == "__main__":
    main()
