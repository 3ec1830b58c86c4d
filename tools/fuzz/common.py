"""What every part of the fault campaign shares: the tally of outcomes and a bounded command run.

A run of the real command (``frisicp register``, ``frisicp bag``, ``register_node``) on hostile
input has one of these outcomes, counted per part: it ended with an exit code the docs give for
that input, or it crashed (a code they do not give, or killed by a signal), printed a traceback,
hung (still running at its deadline: killed, with its process group), lost results (fewer
results kept than it said, or no answer for a registrable pair), published a wrong answer (a
pose marked usable that is not the truth), ignored a signal (ran on to its end), or refused
input with an unclear error (exit 2 without one line naming the problem).
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

BIN = Path(sys.executable).parent  # the venv's console scripts: frisicp, register_node


@dataclass
class Tally:
    """The outcomes of one part; ``problems`` keeps the first few findings, said in full."""

    part: str
    tried: int = 0
    crashes: int = 0
    tracebacks: int = 0
    hangs: int = 0
    lost_results: int = 0
    wrong_answers: int = 0
    ignored_signals: int = 0  # a run that went on to its end after SIGINT or SIGTERM
    unclear_errors: int = 0  # exit 2 without the one line that names the problem
    exits: Counter[str] = field(default_factory=Counter)
    notes: Counter[str] = field(default_factory=Counter)  # what else was sent or seen, counted
    problems: list[str] = field(default_factory=list)

    def problem(self, kind: str, what: str) -> None:
        setattr(self, kind, getattr(self, kind) + 1)
        if len(self.problems) < 20:
            self.problems.append(f"{kind}: {what}")

    @property
    def failures(self) -> int:
        return (
            self.crashes
            + self.tracebacks
            + self.hangs
            + self.lost_results
            + self.wrong_answers
            + self.ignored_signals
        )

    def line(self) -> str:
        exits = ", ".join(f"{code}: {count}" for code, count in sorted(self.exits.items()))
        notes = "".join(f"; {name} {count}" for name, count in sorted(self.notes.items()))
        return (
            f"{self.part}: {self.tried} tried; crashes {self.crashes}, tracebacks {self.tracebacks},"
            f" hangs {self.hangs}, lost results {self.lost_results}, wrong answers {self.wrong_answers},"
            f" ignored signals {self.ignored_signals}, unclear errors {self.unclear_errors}"
            f" (exit codes {exits}){notes}"
        )


@dataclass(frozen=True)
class Finished:
    code: int | None  # None: hung, killed at the deadline
    out: str
    err: str
    seconds: float


def run(command: Sequence[str | Path], timeout: float, env: dict[str, str] | None = None) -> Finished:
    """Run ``command`` in its own session; at ``timeout`` kill its whole group (a hang)."""
    started = time.monotonic()
    process = subprocess.Popen(
        [str(part) for part in command],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        errors="replace",
        start_new_session=True,
        env=env,
    )
    try:
        out, err = process.communicate(timeout=timeout)
        code: int | None = process.returncode
    except subprocess.TimeoutExpired:
        os.killpg(process.pid, signal.SIGKILL)
        out, err = process.communicate()
        code = None
    return Finished(code, out, err, time.monotonic() - started)


def judge_exit(tally: Tally, finished: Finished, allowed: set[int], what: str) -> bool:
    """Count the run's exit; True when it ended with an allowed code and no traceback."""
    tally.tried += 1
    tally.exits["hang" if finished.code is None else str(finished.code)] += 1
    if finished.code is None:
        tally.problem("hangs", what)
        return False
    clean = True
    if "Traceback (most recent call last)" in finished.err:
        tally.problem("tracebacks", f"{what}: {finished.err.strip().splitlines()[-1][:200]}")
        clean = False
    if finished.code not in allowed:
        tally.problem("crashes", f"{what}: exit {finished.code}: {finished.err.strip()[-300:]}")
        clean = False
    return clean


def niced() -> None:
    """The campaign shares the machine: lowest CPU priority for it and what it starts."""
    os.nice(19 - os.nice(0))
