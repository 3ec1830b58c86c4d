"""Where this package's console scripts are installed, as the tests run them.

A venv (`pip install -e .`) puts them beside the interpreter; `colcon build` puts them in
``<prefix>/lib/frisicp_ros/`` (setup.cfg's install_scripts), which is not on PATH: `ros2 run`
finds them there through the ament index, and so does :func:`installed_script`.
"""

from __future__ import annotations

import os
import shutil
import sys
from pathlib import Path

PACKAGE = "frisicp_ros"


def installed_script(name: str) -> str:
    """The path of console script ``name``: beside the interpreter, in a colcon install prefix on
    AMENT_PREFIX_PATH, or on PATH. Fails the calling test with the places looked at."""
    candidates = [Path(sys.executable).parent / name]
    candidates += [
        Path(prefix) / "lib" / PACKAGE / name
        for prefix in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep)
        if prefix
    ]
    for candidate in candidates:
        if os.access(candidate, os.X_OK):
            return str(candidate)
    on_path = shutil.which(name)
    if on_path:
        return on_path
    raise AssertionError(f"console script {name!r} not found in {[str(c) for c in candidates]} or on PATH")
