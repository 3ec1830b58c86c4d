"""Point cloud files, read as (N, m) float64 coordinates, and scan poses of ``.conf`` files.

PLY through plyfile (ASCII and binary), PCD through pypcd4 (ascii, binary and
binary_compressed), XYZ/CSV/TXT through numpy (an optional header line), NPY through numpy.
The file libraries are imported when a file of theirs is read.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np

from frisicp_core.similarity import FloatArray, Similarity


class CloudFileError(ValueError):
    """A point cloud file that cannot be read; the message names the file and the problem."""


def read_points(path: str | Path) -> FloatArray:
    """Coordinates of a point cloud file: x, y and z (z only if present) as an (N, m) array."""
    file = Path(path)
    _check_regular_file(file)
    suffix = file.suffix.lower()
    try:
        if suffix == ".ply":
            return _read_ply(file)
        if suffix == ".pcd":
            return _read_pcd(file)
        if suffix == ".npy":
            return _as_points(np.load(file, allow_pickle=False), file)
        if suffix in (".xyz", ".csv", ".txt", ".pts"):
            return _read_text(file)
    except CloudFileError:
        raise
    except Exception as err:  # noqa: BLE001 - any parser failure becomes one clear message
        raise CloudFileError(f"{file}: cannot read it as {suffix[1:].upper()} ({_one_line(err)})") from None
    raise CloudFileError(f"{file}: unknown extension {suffix!r} (use .ply, .pcd, .xyz, .csv, .txt or .npy)")


def _check_regular_file(file: Path) -> None:
    """Refuse what is not a non-empty regular file, saying what it is (opening a FIFO would wait
    for a writer forever)."""
    if not file.exists():
        raise CloudFileError(f"{file}: no such file")
    if file.is_dir():
        raise CloudFileError(f"{file}: is a directory, not a point cloud file")
    if not file.is_file():
        raise CloudFileError(
            f"{file}: not a regular file (a FIFO, socket or device); give a point cloud file"
        )
    if file.stat().st_size == 0:
        raise CloudFileError(f"{file}: the file is empty (0 bytes)")


def _one_line(err: Exception) -> str:
    """A parser's message as one line. pydantic (pypcd4's header model) lists each missing field
    on lines of their own with a web link: said here as the fields the header lacks."""
    errors = getattr(err, "errors", None)
    if callable(errors) and type(err).__name__ == "ValidationError":
        fields = [".".join(str(part) for part in entry.get("loc", ())) for entry in errors()]
        return f"the header is incomplete or invalid: {', '.join(fields)}"
    return " ".join(str(err).split())


def read_scan_pose(conf: str | Path, name: str) -> Similarity:
    """Pose of scan ``name`` in the common frame, from a Stanford-style ``.conf`` file.

    A line ``bmesh NAME tx ty tz qi qj qk qw`` maps a scan point p to ``R(q)^T p + t``
    (the transpose is the convention the bunny data's README checks). Units are the file's.
    """
    file = Path(conf)
    for line in file.read_text().splitlines():
        fields = line.split()
        if fields[:2] == ["bmesh", name]:
            values = np.array(fields[2:9], dtype=np.float64)
            rotation = Similarity.from_quaternion(1.0, values[3:7], np.zeros(3)).rotation
            return Similarity(1.0, rotation.T, values[:3])
    raise CloudFileError(f"{file} has no 'bmesh {name}' line")


def _as_points(array: np.ndarray, file: Path) -> FloatArray:
    if np.iscomplexobj(array):
        raise CloudFileError(f"{file}: holds complex numbers ({array.dtype}), not coordinates")
    pts = np.asarray(array, dtype=np.float64)
    if pts.ndim != 2 or pts.shape[1] < 2:
        raise CloudFileError(f"{file}: expected rows of at least 2 coordinates, got shape {pts.shape}")
    return pts


def _read_ply(file: Path) -> FloatArray:
    from plyfile import PlyData

    with warnings.catch_warnings():
        # Scans often declare an empty face element, which makes numpy's loadtxt warn.
        warnings.filterwarnings("ignore", message="loadtxt: input contained no data")
        vertex = PlyData.read(str(file))["vertex"]
    names = [p.name for p in vertex.properties]
    axes = [a for a in ("x", "y", "z") if a in names]
    if axes[:2] != ["x", "y"]:
        raise CloudFileError(f"{file}: the vertex element has no x and y properties ({names})")
    return np.column_stack([np.asarray(vertex[a], dtype=np.float64) for a in axes])


def _read_text(file: Path) -> FloatArray:
    with file.open() as handle:
        first = handle.readline()
    delimiter = "," if "," in first else None
    try:
        float(first.replace(",", " ").split()[0])
        skip = 0
    except (ValueError, IndexError):
        skip = 1  # a header line
    with warnings.catch_warnings():
        # A header and no rows: said below as "no points", not as numpy's warning on stderr.
        warnings.filterwarnings("ignore", message="loadtxt: input contained no data")
        table = np.loadtxt(file, delimiter=delimiter, skiprows=skip, ndmin=2)
    if table.size == 0:
        raise CloudFileError(f"{file}: no points (a header line and no rows)")
    return _as_points(table[:, : min(3, table.shape[1])], file)


def _read_pcd(file: Path) -> FloatArray:
    from pypcd4.pypcd4 import PointCloud  # the package root re-exports it implicitly

    cloud = PointCloud.from_path(file)
    axes = tuple(a for a in ("x", "y", "z") if a in cloud.fields)
    if axes[:2] != ("x", "y"):
        raise CloudFileError(f"{file}: PCD has no x and y fields ({cloud.fields})")
    return np.asarray(cloud.numpy(axes), dtype=np.float64)
