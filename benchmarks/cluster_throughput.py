"""`frisicp bag` on a Dask cluster on this machine beside `--jobs 1/2`: pairs per second, the
scheduling overhead per pair, and what an in-process LocalCluster would cost instead of the pool.

Writes the rosbag2 of benchmarks/bag_throughput.py (one model, N data clouds of the same size,
a different similarity each) and times the real command end to end, every pair registered cold
and in full (--no-warm-start --max-points 0: the same work for every executor), JSONL only,
every process at OMP_NUM_THREADS=1 (as the pool's and the cluster's workers run):

- `--jobs 1` and `--jobs 2` (this machine's process pool);
- `--scheduler` with 1 and 2 workers: `dask scheduler` and `dask worker --nthreads 1 --no-nanny`
  processes started before the run (as a cluster is, on a real one), the registration code
  imported on the workers before it (long-lived workers have; the import is timed apart). The
  client's connection is part of the run's time.

Every configuration runs ``--repeats`` times, round robin; the best (shortest) run is the figure,
since other work on a shared machine only ever slows a run down (the median is printed beside
it). The lines of every run are checked equal to `--jobs 1`'s (without the timing field).

Scheduling overhead per pair, three ways: (a) end to end, (one-worker cluster - `--jobs 1`) /
pairs: everything the cluster adds (connection, task round trips, the worker reading its chunk
from the bag, results back); (b) the round trip of an empty task on the one-worker cluster,
divided by the 8 pairs of a chunk; (c) a worker reading one chunk's clouds from the bag
(frisicp_ros.bag.locate), per pair.

LocalCluster: the time from creating `LocalCluster(n_workers=2, threads_per_worker=1)` to the
first result and to its close, beside the pool's (ProcessPoolExecutor, spawn), best of five;
and what a Ctrl-C to the process group does to a LocalCluster run (exit code, time to exit,
tracebacks printed).

    nice -n 10 python benchmarks/cluster_throughput.py            # 60 pairs of 30,000 points, 3 tries
    python benchmarks/cluster_throughput.py --pairs 16 --points 5000   # a quick look
    python benchmarks/cluster_throughput.py --quick   # every section once: 4 pairs of 2,000 points
"""

from __future__ import annotations

import json
import multiprocessing
import os
import platform
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from concurrent.futures import ProcessPoolExecutor
from contextlib import contextmanager
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))
from bag_throughput import DATA_TOPIC, MODEL_TOPIC, write_bag

from frisicp_bench import script

BIN = Path(sys.executable).parent
ONE_THREAD = {"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}


WORKER_WARM_UP: list[float] = []  # seconds for fresh workers to import the registration code


def import_registration_code() -> None:
    import frisicp_ros.bag.cluster  # noqa: F401 - what a task of frisicp bag needs


@contextmanager
def dask_cluster(workdir: Path, workers: int) -> Iterator[str]:
    """A scheduler and ``workers`` one-thread workers on 127.0.0.1; yields the scheduler file."""
    from distributed import Client

    scheduler_file = workdir / f"scheduler-{workers}.json"
    scheduler_file.unlink(missing_ok=True)  # the address of an earlier cluster
    env = {**os.environ, **ONE_THREAD}
    quiet = {"stdout": subprocess.DEVNULL, "stderr": subprocess.DEVNULL, "start_new_session": True}
    command = [str(BIN / "dask"), "scheduler", "--host", "127.0.0.1", "--port", "0", "--no-dashboard"]
    processes = [subprocess.Popen([*command, "--scheduler-file", str(scheduler_file)], env=env, **quiet)]
    try:
        while not scheduler_file.exists() or not scheduler_file.read_text().strip().endswith("}"):
            time.sleep(0.05)
        for number in range(workers):
            command = [
                str(BIN / "dask"),
                "worker",
                "--scheduler-file",
                str(scheduler_file),
                "--host",
                "127.0.0.1",
            ]
            command += ["--nthreads", "1", "--no-nanny", "--no-dashboard", "--name", f"w{number}"]
            processes.append(subprocess.Popen(command, env=env, **quiet))
        with Client(scheduler_file=str(scheduler_file), set_as_default=False) as client:
            client.wait_for_workers(workers, timeout=120)
            # Long-lived workers have imported the registration code before a run; fresh ones
            # pay it on their first task (printed separately, not part of the runs' figures).
            started = time.perf_counter()
            client.run(import_registration_code)
            WORKER_WARM_UP.append(time.perf_counter() - started)
        yield str(scheduler_file)
    finally:
        for process in processes:
            os.killpg(process.pid, signal.SIGKILL)
            process.wait()


def frisicp_bag(bag: Path, out: Path, executor: list[str]) -> dict[str, float]:
    command = [
        str(BIN / "frisicp"),
        "bag",
        str(bag),
        "--model-topic",
        MODEL_TOPIC,
        "--data-topic",
        DATA_TOPIC,
    ]
    command += ["--max-points", "0", "--no-warm-start", "--out", str(out), "--no-progress", *executor]
    started = time.perf_counter()
    # One OpenMP thread here too: the pool's workers and the cluster's run so, and --jobs 1 in
    # this process would otherwise busy-wait threads on every core (docs/bag.md).
    subprocess.run(command, check=True, stderr=subprocess.DEVNULL, env={**os.environ, **ONE_THREAD})
    wall = time.perf_counter() - started
    records = [json.loads(line) for line in out.read_text().splitlines()]
    return {
        "pairs": len(records),
        "wall_seconds": wall,
        "pairs_per_second": len(records) / wall,
        "core_seconds": sum(r["seconds"] for r in records),
        "load_average_1min": os.getloadavg()[0],
    }


def lines_without_timing(path: Path) -> list[dict]:
    return [
        {k: v for k, v in json.loads(line).items() if k != "seconds"}
        for line in path.read_text().splitlines()
    ]


def empty_task_round_trip(scheduler_file: str, tasks: int = 200) -> float:
    """Seconds per task of submitting an empty task and waiting for its result, one at a time."""
    from distributed import Client

    with Client(scheduler_file=scheduler_file, set_as_default=False) as client:
        client.submit(len, [], pure=False).result()  # the connection to the worker is set up
        started = time.perf_counter()
        for _ in range(tasks):
            client.submit(len, [], pure=False).result()
        return (time.perf_counter() - started) / tasks


def chunk_reading_per_pair(bag: Path) -> float:
    """Seconds per pair for a worker to read a chunk's clouds back from the bag (all chunks)."""
    from frisicp_ros.bag.executors import WARM_START_CHUNK
    from frisicp_ros.bag.locate import BagSource, locate, read_pairs
    from frisicp_ros.bag.pairs import PairReading
    from frisicp_ros.bag.reader import open_bag
    from frisicp_ros.stream.settings import settings_from

    source = BagSource.of(bag, MODEL_TOPIC, DATA_TOPIC)
    with open_bag(bag) as reader:
        located = [
            locate(pair, source)
            for pair in PairReading.paired_as(settings_from({}), reader, MODEL_TOPIC, DATA_TOPIC)
        ]
    started = time.perf_counter()
    for first in range(0, len(located), WARM_START_CHUNK):
        read_pairs(source, located[first : first + WARM_START_CHUNK])
    return (time.perf_counter() - started) / len(located)


def echo(value: int) -> int:
    return value


def start_up_seconds(repeats: int = 5) -> dict[str, float]:
    """Bests of ``repeats``: a 2-process pool and a 2-worker LocalCluster, to the first result and closed."""
    from distributed import Client, LocalCluster

    pool, cluster_first, cluster_closed = [], [], []
    for _ in range(repeats):
        started = time.perf_counter()
        with ProcessPoolExecutor(2, mp_context=multiprocessing.get_context("spawn")) as executor:
            list(executor.map(echo, range(2)))
        pool.append(time.perf_counter() - started)
        started = time.perf_counter()
        with (
            LocalCluster(
                n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None
            ) as cluster,
            Client(cluster) as client,
        ):
            client.gather(client.map(echo, range(2)))
            cluster_first.append(time.perf_counter() - started)
        cluster_closed.append(time.perf_counter() - started)
    return {
        "pool_to_closed": min(pool),
        "local_cluster_to_first_result": min(cluster_first),
        "local_cluster_to_closed": min(cluster_closed),
    }


LOCAL_CLUSTER_RUN = """
import time
from distributed import Client, LocalCluster
def slow(x):
    time.sleep(5)
    return x
if __name__ == "__main__":
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster, Client(cluster) as client:
        print("up", flush=True)
        client.gather(client.map(slow, range(8)))
"""


def local_cluster_ctrl_c(workdir: Path) -> dict[str, object]:
    """A Ctrl-C (SIGINT to the process group, as a terminal sends it) one second into a
    LocalCluster run of 5-second tasks: exit code, seconds until exit, tracebacks printed."""
    script = workdir / "local_cluster_run.py"
    script.write_text(LOCAL_CLUSTER_RUN)
    process = subprocess.Popen(
        [sys.executable, str(script)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
    )
    assert process.stdout is not None
    process.stdout.readline()
    time.sleep(1.0)
    os.killpg(process.pid, signal.SIGINT)
    sent = time.perf_counter()
    _, err = process.communicate(timeout=120)
    exited = time.perf_counter() - sent
    outlived = 0.0  # how long its worker processes outlived it
    while True:
        try:
            os.killpg(process.pid, 0)
        except ProcessLookupError:
            break
        outlived = time.perf_counter() - sent - exited
        if outlived > 30:
            os.killpg(process.pid, signal.SIGKILL)
            break
        time.sleep(0.05)
    return {
        "exit_code": process.returncode,
        "seconds_to_exit": exited,
        "tracebacks": err.count("Traceback"),
        "workers_outlived_it_seconds": outlived,
    }


def main() -> int:
    parser = script.parser(
        __file__,
        __doc__,
        "every section once: 4 pairs of 2,000-point clouds (one chunk), one try, one start-up",
        repeats=3,
        json_out=True,
    )
    parser.add_argument("--pairs", type=int, default=60)
    parser.add_argument("--points", type=int, default=30000)
    args = script.parse(parser)
    start_up_repeats = 5
    if args.quick:
        args.pairs, args.points, args.repeats, start_up_repeats = 4, 2000, 1, 1
    with tempfile.TemporaryDirectory() as tmp:
        workdir = Path(tmp)
        bag = workdir / "input"
        write_bag(bag, args.pairs, args.points)
        tries: dict[str, list[dict[str, float]]] = {}
        outputs: dict[str, Path] = {}
        task_round_trips = []
        # Round robin, so load from other work on the machine spreads over every configuration;
        # the best of the tries is the figure (interference only ever slows a run down).
        for _ in range(args.repeats):
            for jobs in (1, 2):
                name = f"--jobs {jobs}"
                outputs[name] = workdir / f"jobs{jobs}.jsonl"
                tries.setdefault(name, []).append(frisicp_bag(bag, outputs[name], ["--jobs", str(jobs)]))
            for workers in (1, 2):
                name = f"--scheduler, {workers} worker{'s' if workers > 1 else ''}"
                outputs[name] = workdir / f"dask{workers}.jsonl"
                with dask_cluster(workdir, workers) as scheduler_file:
                    tries.setdefault(name, []).append(
                        frisicp_bag(bag, outputs[name], ["--scheduler", scheduler_file])
                    )
                    if workers == 1:
                        task_round_trips.append(empty_task_round_trip(scheduler_file))
        runs = {name: min(results, key=lambda r: r["wall_seconds"]) for name, results in tries.items()}
        for name, results in tries.items():
            runs[name]["median_pairs_per_second"] = statistics.median(r["pairs_per_second"] for r in results)
        overhead_task = min(task_round_trips)
        reference = lines_without_timing(outputs["--jobs 1"])
        identical = {name: lines_without_timing(path) == reference for name, path in outputs.items()}
        reading = chunk_reading_per_pair(bag)
        start_up = start_up_seconds(start_up_repeats)
        ctrl_c = local_cluster_ctrl_c(workdir)
    end_to_end = (
        runs["--scheduler, 1 worker"]["wall_seconds"] - runs["--jobs 1"]["wall_seconds"]
    ) / args.pairs
    print(
        f"machine: {platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}; "
        f"date {time.strftime('%Y-%m-%d')}; niceness {os.nice(0)}"
    )
    print(f"bag: {args.pairs} pairs of {args.points}-point clouds (rosbag2, mcap), every pair cold, in full")
    for name, result in runs.items():
        print(
            f"{name}: {result['pairs_per_second']:.2f} pairs/s (median of the tries "
            f"{result['median_pairs_per_second']:.2f}), wall {result['wall_seconds']:.1f} s, "
            f"in register {result['core_seconds']:.1f} s, lines identical to --jobs 1: {identical[name]}, "
            f"load average at the end {result['load_average_1min']:.1f}"
        )
    print(
        f"scheduling overhead per pair: end to end {1000 * end_to_end:.1f} ms "
        f"(best one-worker cluster run minus best --jobs 1 run); empty task round trip {1000 * overhead_task:.2f} ms per task, "
        f"{1000 * overhead_task / 8:.2f} ms per pair (8 per task); a worker reading its chunk from the bag "
        f"{1000 * reading:.2f} ms per pair"
    )
    print(
        f"fresh workers importing the registration code (once per worker, before the runs): {min(WORKER_WARM_UP):.2f} s"
    )
    print(
        f"start-up: process pool (2, spawn) to closed {start_up['pool_to_closed']:.2f} s; LocalCluster (2 workers) "
        f"to the first result {start_up['local_cluster_to_first_result']:.2f} s, to closed "
        f"{start_up['local_cluster_to_closed']:.2f} s"
    )
    print(
        f"Ctrl-C in a LocalCluster run: exit code {ctrl_c['exit_code']}, exited after "
        f"{ctrl_c['seconds_to_exit']:.1f} s, {ctrl_c['tracebacks']} tracebacks printed, its worker processes "
        f"outlived it by {ctrl_c['workers_outlived_it_seconds']:.1f} s"
    )
    if args.json:
        figures = {
            "runs": runs,
            "identical_to_jobs_1": identical,
            "overhead_per_pair_seconds": {
                "end_to_end": end_to_end,
                "empty_task_per_pair": overhead_task / 8,
                "chunk_reading": reading,
            },
            "start_up_seconds": start_up,
            "worker_warm_up_seconds": min(WORKER_WARM_UP),
            "local_cluster_ctrl_c": ctrl_c,
        }
        args.json.write_text(json.dumps(figures, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
