"""A real Dask cluster on 127.0.0.1 for the tests: a `dask scheduler` and `dask worker` processes.

Started as the docs tell users to start one (the `dask` command line, no dashboard), each process
in its own session, so a Ctrl-C sent to `frisicp bag`'s process group does not reach them (as on
a real cluster). :meth:`LocalDaskCluster.stop` kills every process it started, also when a test
failed; should the test run itself be killed, the scheduler ends after ``IDLE_TIMEOUT`` idle and
the workers after ``DEATH_TIMEOUT`` without it.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from collections.abc import Sequence
from pathlib import Path

DASK = Path(sys.executable).parent / "dask"
IDLE_TIMEOUT = "120s"
DEATH_TIMEOUT = "30s"
START_TIMEOUT_SEC = 60.0


class LocalDaskCluster:
    def __init__(self, workdir: Path) -> None:
        self.workdir = workdir
        self.scheduler_file = workdir / "scheduler.json"
        self.processes: list[subprocess.Popen[bytes]] = []
        self.workers: dict[str, subprocess.Popen[bytes]] = {}  # name -> process

    @property
    def address(self) -> str:
        return str(json.loads(self.scheduler_file.read_text())["address"])

    def start(self, workers: int, wrapper: Sequence[str] = ()) -> LocalDaskCluster:
        """The scheduler and ``workers`` one-thread workers (each command prefixed by ``wrapper``)."""
        command = [str(DASK), "scheduler", "--host", "127.0.0.1", "--port", "0", "--no-dashboard"]
        command += ["--scheduler-file", str(self.scheduler_file), "--idle-timeout", IDLE_TIMEOUT]
        self._spawn("scheduler", command)
        self._wait_for(self._address_written, "the scheduler's address file")
        for _ in range(workers):
            self.add_worker(wrapper)
        self.wait_for_workers(workers)
        return self

    def add_worker(self, wrapper: Sequence[str] = ()) -> str:
        name = f"w{len(self.workers)}"
        command = [*wrapper, str(DASK), "worker", "--scheduler-file", str(self.scheduler_file)]
        command += ["--host", "127.0.0.1", "--nthreads", "1", "--no-nanny", "--no-dashboard"]
        command += ["--name", name, "--death-timeout", DEATH_TIMEOUT]
        self.workers[name] = self._spawn(name, command)
        return name

    def client(self):  # a distributed.Client for the test's own questions to the scheduler
        from distributed import Client

        return Client(self.address, timeout="20s", set_as_default=False)

    def wait_for_workers(self, count: int) -> None:
        with self.client() as client:
            client.wait_for_workers(count, timeout=START_TIMEOUT_SEC)

    def kill_a_worker_running(self, key_prefix: str) -> str:
        """SIGKILL a worker that is running a task whose key starts with ``key_prefix``; its name."""
        deadline = time.monotonic() + 30
        with self.client() as client:
            names = {address: info["name"] for address, info in client.scheduler_info()["workers"].items()}
            while time.monotonic() < deadline:
                for address, keys in client.processing().items():
                    if any(str(key).startswith(key_prefix) for key in keys):
                        name = names[address]
                        self.workers[name].kill()
                        self.workers[name].wait(10)
                        return name
                time.sleep(0.01)
        raise AssertionError(f"no worker ran a task {key_prefix}* within 30 s")

    def tasks(self, key_prefix: str) -> list[str]:
        """The keys starting with ``key_prefix`` the scheduler still holds."""
        with self.client() as client:
            keys = client.run_on_scheduler(lambda dask_scheduler: [str(key) for key in dask_scheduler.tasks])
        return [key for key in keys if key.startswith(key_prefix)]

    def alive(self) -> list[str]:
        return [name for name, process in self.workers.items() if process.poll() is None]

    def stop(self) -> None:
        for process in self.processes:
            if process.poll() is None:
                os.killpg(process.pid, signal.SIGKILL)
        for process in self.processes:
            process.wait(10)

    def _spawn(self, name: str, command: list[str]) -> subprocess.Popen[bytes]:
        log = (self.workdir / f"{name}.log").open("wb")
        # One thread per registration, as `frisicp bag`'s own workers run (docs/bag.md).
        env = {**os.environ, "OMP_NUM_THREADS": "1"}
        process = subprocess.Popen(command, stdout=log, stderr=log, env=env, start_new_session=True)
        log.close()
        self.processes.append(process)
        return process

    def _address_written(self) -> bool:
        try:
            return bool(self.address)
        except (OSError, ValueError, KeyError):  # not yet, or half written
            return False

    def _wait_for(self, condition, what: str) -> None:
        deadline = time.monotonic() + START_TIMEOUT_SEC
        while not condition():
            if time.monotonic() > deadline or any(p.poll() is not None for p in self.processes):
                raise RuntimeError(f"{what} did not appear; logs in {self.workdir}")
            time.sleep(0.05)
