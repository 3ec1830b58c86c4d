"""Hostile files to ``frisicp register``: every one must end in exit 0 or 1 with a right answer, or
exit 2 with one line naming the problem; never a traceback, a hang or a wrong answer.

Each case is a (data, model) pair of files written here from a synthetic surface (no data files
needed), with the truth when the pair is registrable.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from common import BIN, Tally, judge_exit, run

from frisicp_core import Similarity, axis_angle_rotation, bumpy_surface, rotation_angle

SHAPE = bumpy_surface(3000, seed=4)
TRUTH = Similarity(1.7, axis_angle_rotation((0.3, 1.0, 0.2), 0.6), [0.4, -0.2, 1.0])


@dataclass(frozen=True)
class Case:
    name: str
    data: Path
    model: Path
    truth: Similarity | None  # None: nothing registrable; exit 2 (or 1, an unreliable result)


def _save(path: Path, points: np.ndarray) -> Path:
    np.save(path, points)
    return path


def _text(path: Path, content: bytes) -> Path:
    path.write_bytes(content)
    return path


def _ply(path: Path, points: np.ndarray, binary: bool = True) -> Path:
    from plyfile import PlyData, PlyElement

    vertex = np.array([tuple(p) for p in points], dtype=[("x", "f8"), ("y", "f8"), ("z", "f8")])
    PlyData([PlyElement.describe(vertex, "vertex")], text=not binary).write(str(path))
    return path


def _byte_swapped(points: np.ndarray) -> np.ndarray:
    with np.errstate(invalid="ignore"):
        swapped = points.astype("<f4").view(">f4").astype(np.float64)
    return swapped[np.isfinite(swapped).all(axis=1)]


def cases(root: Path, rng: np.random.Generator) -> Iterator[Case]:
    """The hostile classes, each with random details from ``rng``; one of each per round."""
    model = _save(root / "model.npy", TRUTH.apply(SHAPE))
    data_points = SHAPE[rng.permutation(len(SHAPE))[:2400]]
    good = _save(root / "data.npy", data_points)
    unit = 10.0 ** rng.uniform(-250, 250)
    nothing: list[tuple[str, Callable[[], Path]]] = [
        ("missing file", lambda: root / "missing.ply"),
        ("directory", lambda: _mkdir(root / "folder.ply")),
        ("FIFO", lambda: _fifo(root / "pipe.xyz")),
        ("empty .pcd", lambda: _text(root / "empty.pcd", b"")),
        ("empty .ply", lambda: _text(root / "empty.ply", b"")),
        ("header-only .xyz", lambda: _text(root / "header.xyz", b"x y z\n")),
        ("junk .pcd", lambda: _text(root / "junk.pcd", rng.bytes(int(rng.integers(1, 3000))))),
        ("junk .ply", lambda: _text(root / "junk.ply", b"ply\n" + rng.bytes(int(rng.integers(1, 3000))))),
        ("junk .npy", lambda: _text(root / "junk.npy", rng.bytes(int(rng.integers(1, 3000))))),
        ("truncated .ply", lambda: _truncated(_ply(root / "cut.ply", data_points), rng)),
        ("unknown extension", lambda: _text(root / "cloud.obj", b"v 1 2 3\n")),
        ("all NaN", lambda: _save(root / "nan.npy", np.full((100, 3), np.nan))),
        ("complex", lambda: _save(root / "complex.npy", data_points * 1j)),
        ("strings", lambda: _text(root / "words.csv", b"a,b,c\nd,e,f\ng,h,i\nj,k,l\n")),
        ("one column", lambda: _save(root / "column.npy", rng.normal(size=(100, 1)))),
        ("3-D array", lambda: _save(root / "cube.npy", rng.normal(size=(4, 4, 3)))),
        ("too few points", lambda: _save(root / "few.npy", rng.normal(size=(int(rng.integers(1, 4)), 3)))),
        ("identical points", lambda: _save(root / "same.npy", np.ones((200, 3)) * rng.normal(size=3))),
        ("collinear", lambda: _save(root / "line.npy", np.outer(rng.random(200), rng.normal(size=3)))),
        ("wrong byte order", lambda: _save(root / "swapped.npy", _byte_swapped(data_points))),
        ("random numbers", lambda: _save(root / "random.npy", _byte_swapped(rng.normal(size=(2000, 3))))),
        ("far outlier", lambda: _save(root / "outlier.npy", _with_outlier(data_points, rng))),
        ("2-D against 3-D", lambda: _save(root / "planar.npy", data_points[:, :2])),
    ]
    for name, make in nothing:
        yield Case(name, make(), model, None)
    yield Case(
        "data in units 10^k times the model's",
        _save(root / "big.npy", data_points * unit),
        model,
        _in_units(unit),
    )
    tiny = 10.0 ** rng.uniform(-300, -200)
    yield Case(
        "both clouds at 1e-250",
        _save(root / "tiny_data.npy", data_points * tiny),
        _save(root / "tiny_model.npy", TRUTH.apply(SHAPE) * tiny),
        Similarity(TRUTH.scale, TRUTH.rotation, TRUTH.translation * tiny),
    )
    yield Case("valid pair (binary PLY)", _ply(root / "good.ply", data_points), model, TRUTH)
    yield Case("valid pair (NPY)", good, model, TRUTH)


def _in_units(unit: float) -> Similarity:
    return Similarity(TRUTH.scale / unit, TRUTH.rotation, TRUTH.translation)


def _mkdir(path: Path) -> Path:
    path.mkdir(exist_ok=True)
    return path


def _fifo(path: Path) -> Path:
    if not path.exists():
        os.mkfifo(path)
    return path


def _truncated(path: Path, rng: np.random.Generator) -> Path:
    raw = path.read_bytes()
    path.write_bytes(raw[: int(len(raw) * rng.uniform(0.05, 0.95))])
    return path


def _with_outlier(points: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    far = points.copy()
    far[int(rng.integers(len(far)))] = [10.0 ** rng.uniform(20, 300), 0.0, 0.0]
    return far


def right(answer: dict[str, object], truth: Similarity) -> bool:
    """The JSON answer is the truth: rotation within 1 degree, scale and translation within 1 %."""
    scale = float(answer["scale"])  # type: ignore[arg-type]
    rotation = np.array(answer["rotation"], dtype=float)
    translation = np.array(answer["translation"], dtype=float)
    size = max(float(np.linalg.norm(truth.translation)), 1e-300)
    return bool(
        abs(scale / truth.scale - 1) < 0.01
        and np.degrees(rotation_angle(rotation.T @ truth.rotation)) < 1.0
        and np.linalg.norm(translation - truth.translation) < 0.01 * size
    )


def campaign(root: Path, rng: np.random.Generator, rounds: int, deadline: float) -> Tally:
    import json
    import time

    tally = Tally("frisicp register, hostile files")
    for round_number in range(rounds):
        folder = root / f"round{round_number}"
        folder.mkdir(parents=True, exist_ok=True)
        for case in cases(folder, rng):
            if time.monotonic() > deadline:
                return tally
            finished = run([BIN / "frisicp", "register", case.data, case.model, "--json"], timeout=120)
            if not judge_exit(tally, finished, {0, 1, 2}, case.name):
                continue
            if finished.code == 2 and finished.err.count("\n") != 1:
                lines = finished.err.count("\n")
                tally.problem("unclear_errors", f"{case.name}: exit 2 with {lines} lines")
            if finished.code == 0:  # a usable pose: it must be the truth
                answer = json.loads(finished.out)
                if case.truth is None or not right(answer, case.truth):
                    tally.problem("wrong_answers", f"{case.name}: {finished.out[:200]}")
            elif case.truth is not None:
                said = (finished.err.strip() or finished.out)[:200]
                tally.problem("lost_results", f"{case.name}: no answer for a registrable pair: {said}")
    return tally
