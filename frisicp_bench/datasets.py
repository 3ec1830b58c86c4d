"""The real data of ../shared/data: MPEG-7 contours, Stanford bunny point sets and scan poses.

Nothing is copied into the repository; every loader raises :class:`DataMissingError` with the
path it looked for when the data is absent.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from frisicp_core import CloudFileError, FloatArray, Similarity, read_points, read_scan_pose

from .contours import outer_contour

# Where the data is when --data is not given: this variable, else shared/data beside the repository.
DATA_DIR_VARIABLE = "FRISICP_DATA"

# The bunny PLY files are in metres; the benchmark works in millimetres so RMS values read
# naturally (the scans' noise is a fraction of a millimetre).
MILLIMETRES_PER_METRE = 1000.0


def repository_root() -> Path:
    """The checkout this package is imported from; for an installed copy (no checkout around it),
    the current directory, taken to be the repository root (where ``make`` runs)."""
    checkout = Path(__file__).resolve().parents[1]
    return (
        checkout if (checkout / "setup.py").is_file() and (checkout / "package.xml").is_file() else Path.cwd()
    )


def default_data_dir() -> Path:
    """``$FRISICP_DATA`` if set, else ``shared/data`` beside the repository (``../shared/data``
    from :func:`repository_root`): ``frisicp bench``, the scripts in ``benchmarks/`` and the tests
    all look here."""
    return Path(os.environ.get(DATA_DIR_VARIABLE) or repository_root().parent / "shared" / "data")


class DataMissingError(FileNotFoundError):
    """A data file the benchmark needs is not there; the message says which and where."""


def require(path: Path) -> Path:
    if not path.exists():
        raise DataMissingError(
            f"{path} is missing: the benchmark reads the real data from ../shared/data beside the "
            "repository, $FRISICP_DATA or --data DIR; it is not shipped with the package"
        )
    return path


def silhouette_contour(data_dir: Path, shape_class: str, instance: int) -> FloatArray:
    """Outer contour (pixels, y up) of MPEG-7 ``CLASS-K.gif``."""
    from PIL import Image  # the bench extra; only the 2-D families need it

    path = require(data_dir / "mpeg7" / f"{shape_class}-{instance}.gif")
    with Image.open(path) as image:
        return outer_contour(np.asarray(image))


def bunny_points(data_dir: Path, name: str) -> FloatArray:
    """Vertices of ``bunny/NAME`` (a .ply file) in millimetres."""
    return read_points(require(data_dir / "bunny" / name)) * MILLIMETRES_PER_METRE


def scan_pose(data_dir: Path, name: str) -> Similarity:
    """Pose of a scan in the common frame, in millimetres, from ``bun.conf``."""
    try:
        pose = read_scan_pose(require(data_dir / "bunny" / "bun.conf"), name)
    except CloudFileError as err:
        raise DataMissingError(str(err)) from None
    return Similarity(1.0, pose.rotation, pose.translation * MILLIMETRES_PER_METRE)
