"""A plain ROS 2 workspace whose Python packages come only from package.xml's keys.

rosdep, apt and the ROS apt repository are not available here, so each key is resolved to its PyPI
equivalent: pip keys through rosdep/frisicp_ros.yaml (as ``rosdep install`` would), the others
through rosdep/pypi.yaml. A dependency package.xml does not declare is therefore missing here too.
The venv is cached under build/clean-env-<hash of its requirements>.

Run as ``make colcon-test`` (``cd test && python -m support.workspace [PYTEST ARGS]``): a fresh
workspace in build/colcon-ws, ``colcon build``, then ``colcon test --packages-select frisicp_ros``
(with the given pytest arguments) and ``colcon test-result --verbose``; the exit code is theirs.
"""

from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import sys
import xml.etree.ElementTree as ET
from collections.abc import Iterable
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parents[2]
BUILD_TOOL = "colcon-common-extensions"
RUNTIME = ("exec_depend",)
RUNTIME_AND_TESTS = ("exec_depend", "test_depend")
SOURCE_IGNORED = (".venv", "build", "install", "log", ".git", "__pycache__", "*.egg-info", ".pytest_cache")


def declared(kinds: Iterable[str] = RUNTIME) -> list[str]:
    """package.xml's keys of the given kinds (exec_depend, test_depend, ...)."""
    root = ET.parse(ROOT / "package.xml").getroot()
    return [element.text or "" for kind in kinds for element in root.iter(kind)]


def pip_keys() -> dict[str, str]:
    """The pip rosdep keys this package defines (rosdep/frisicp_ros.yaml) -> PyPI name."""
    rules = yaml.safe_load((ROOT / "rosdep" / "frisicp_ros.yaml").read_text())
    return {key: rule["ubuntu"]["pip"]["packages"][0] for key, rule in rules.items()}


def pypi_equivalents() -> dict[str, str | None]:
    """Every other key -> its PyPI requirement (None: not on PyPI)."""
    equivalents: dict[str, str | None] = yaml.safe_load((ROOT / "rosdep" / "pypi.yaml").read_text())
    return equivalents


def requirements(kinds: Iterable[str] = RUNTIME) -> list[str]:
    known = {**pypi_equivalents(), **pip_keys()}
    keys = declared(kinds)
    unknown = [key for key in keys if key not in known]
    assert not unknown, f"package.xml names {unknown}: add their PyPI names to rosdep/pypi.yaml"
    return sorted({requirement for key in keys if (requirement := known[key])})


def clean_venv(kinds: Iterable[str] = RUNTIME) -> Path:
    """A venv with exactly the requirements of package.xml's ``kinds`` keys and colcon."""
    wanted = [*requirements(kinds), BUILD_TOOL]
    digest = hashlib.sha256("\n".join([sys.version, *sorted(set(wanted))]).encode()).hexdigest()[:12]
    venv = ROOT / "build" / f"clean-env-{digest}"
    if (venv / "ready").exists():
        return venv
    shutil.rmtree(venv, ignore_errors=True)
    subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True, timeout=120)
    pip = subprocess.run(
        [str(venv / "bin" / "pip"), "install", "--quiet", *wanted],
        capture_output=True,
        text=True,
        timeout=900,
    )
    assert pip.returncode == 0, pip.stderr[-3000:]
    (venv / "ready").write_text("\n".join(wanted) + "\n")
    return venv


def clean_environment(venv: Path, base: dict[str, str], prefix: Path | None = None) -> dict[str, str]:
    """``base``'s settings but none of another Python environment's: no PYTHONPATH, no other venv;
    with ``prefix`` (an install prefix) as colcon's setup scripts would set it."""
    env = {
        key: value for key, value in base.items() if key not in ("PYTHONPATH", "VIRTUAL_ENV", "PYTHONHOME")
    }
    env["PATH"] = f"{venv / 'bin'}{os.pathsep}/usr/bin{os.pathsep}/bin"
    env["VIRTUAL_ENV"] = str(venv)
    env.pop("AMENT_PREFIX_PATH", None)
    if prefix is not None:
        env["PYTHONPATH"] = str(next(prefix.glob("lib/python3*/site-packages")))
        env["AMENT_PREFIX_PATH"] = str(prefix)
    return env


def copy_source(workspace: Path) -> Path:
    """The package's source as ``workspace/src/frisicp_ros``."""
    source = workspace / "src" / "frisicp_ros"
    shutil.copytree(ROOT, source, ignore=shutil.ignore_patterns(*SOURCE_IGNORED))
    return source


def run(command: list[str], cwd: Path, env: dict[str, str]) -> int:
    print("+", " ".join(command), flush=True)
    return subprocess.run(command, cwd=cwd, env=env, check=False).returncode


def main(pytest_args: list[str]) -> int:
    venv = clean_venv(RUNTIME_AND_TESTS)
    workspace = ROOT / "build" / "colcon-ws"
    shutil.rmtree(workspace, ignore_errors=True)
    copy_source(workspace)
    env = clean_environment(venv, {**os.environ, "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"})
    colcon = str(venv / "bin" / "colcon")
    code = run([colcon, "build"], workspace, env)
    if code:
        return code
    test = [colcon, "test", "--packages-select", "frisicp_ros", "--event-handlers", "console_direct+"]
    if pytest_args:
        # colcon reads an argument that starts with a dash as its own unless a space precedes it.
        test += ["--pytest-args", *(f" {arg}" if arg.startswith("-") else arg for arg in pytest_args)]
    run(test, workspace, env)  # its exit code is 0 even when tests fail: test-result tells
    return run(
        [colcon, "test-result", "--verbose", "--test-result-base", "build/frisicp_ros"], workspace, env
    )


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
