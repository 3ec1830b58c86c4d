"""The package in a plain ROS 2 workspace that holds only what package.xml declares.

A fresh venv gets exactly the PyPI equivalents of package.xml's ``exec_depend`` keys (parsed
from package.xml, so a dependency missing there is missing here too) plus colcon, the build tool.
``colcon build`` installs the package; then every module imports, each library dependency is used
once (pykdtree, PLY and PCD reading, rosbags, tqdm), and the installed ``register_node`` starts,
answers on /diagnostics and exits 0 on SIGINT. (``ros2 run`` is a thin wrapper around that
installed script; ``ros2``/``launch`` are not on PyPI: the launch file is checked statically in
test_colcon_build.py.)

The venv is cached under build/clean-env-<hash of its requirements> so later runs cost seconds;
the first run installs from PyPI (about a minute with pip's cache).
"""

from __future__ import annotations

import ast
import hashlib
import os
import shutil
import signal
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
import yaml
from support.ros import ros_environment, spinning_node, wait_until

DOMAIN = 137
ENV = ros_environment(DOMAIN)

from diagnostic_msgs.msg import DiagnosticArray  # noqa: E402

pytestmark = [pytest.mark.ros, pytest.mark.slow]

ROOT = Path(__file__).resolve().parents[2]
# rosdep keys of ROS packages and of standard Python libraries -> PyPI requirement. None: not on
# PyPI (launch, launch_ros: only the launch file needs them; it is checked statically).
ROSDEP_TO_PYPI: dict[str, str | None] = {
    "rclpy": "ros-jazzy-rclpy[fastrtps]",  # with an RMW, so the node can run
    "sensor_msgs": "ros-jazzy-sensor-msgs",
    "geometry_msgs": "ros-jazzy-geometry-msgs",
    "std_msgs": "ros-jazzy-std-msgs",
    "diagnostic_msgs": "ros-jazzy-diagnostic-msgs",
    "std_srvs": "ros-jazzy-std-srvs",
    "rcl_interfaces": "ros-jazzy-rcl-interfaces",
    "ament_index_python": "ros-jazzy-ament-index-python",
    "launch": None,
    "launch_ros": None,
    "python3-numpy": "numpy",
    "python3-scipy": "scipy",
    "python3-tqdm": "tqdm",
}
BUILD_TOOL = "colcon-common-extensions"


def exec_depends() -> list[str]:
    return [element.text or "" for element in ET.parse(ROOT / "package.xml").getroot().iter("exec_depend")]


def pip_keys() -> dict[str, str]:
    """The pip rosdep keys this package defines (rosdep/frisicp_ros.yaml) -> PyPI name."""
    rules = yaml.safe_load((ROOT / "rosdep" / "frisicp_ros.yaml").read_text())
    return {key: rule["ubuntu"]["pip"]["packages"][0] for key, rule in rules.items()}


def requirements() -> list[str]:
    known = {**ROSDEP_TO_PYPI, **pip_keys()}
    unknown = [key for key in exec_depends() if key not in known]
    assert not unknown, f"package.xml names {unknown}: add their PyPI names to ROSDEP_TO_PYPI"
    return sorted(requirement for key in exec_depends() if (requirement := known[key]))


def install_requires() -> list[str]:
    """setup.py's install_requires, as names."""
    tree = ast.parse((ROOT / "setup.py").read_text())
    for node in ast.walk(tree):
        if isinstance(node, ast.keyword) and node.arg == "install_requires":
            names = [ast.literal_eval(item) for item in node.value.elts]  # type: ignore[attr-defined]
            return [name.split(">")[0].split("=")[0].split("<")[0].strip() for name in names]
    raise AssertionError("setup.py has no install_requires")


def test_every_python_requirement_of_setup_py_is_declared_in_package_xml():
    declared = {requirement.split("[")[0] for requirement in requirements()}
    missing = sorted(set(install_requires()) - declared)
    assert not missing, f"setup.py requires {missing} but package.xml does not declare them"


def clean_venv() -> Path:
    wanted = [*requirements(), BUILD_TOOL]
    digest = hashlib.sha256("\n".join([sys.version, *wanted]).encode()).hexdigest()[:12]
    venv = ROOT / "build" / f"clean-env-{digest}"
    if (venv / "ready").exists():
        return venv
    shutil.rmtree(venv, ignore_errors=True)
    subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True, timeout=120)
    pip = subprocess.run(
        [str(venv / "bin" / "pip"), "install", "--quiet", *wanted],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert pip.returncode == 0, pip.stderr[-3000:]
    (venv / "ready").write_text("\n".join(wanted) + "\n")
    return venv


def clean_environment(venv: Path, prefix: Path | None = None) -> dict[str, str]:
    """The dev environment's ROS settings only: no PYTHONPATH, no other venv."""
    env = {key: value for key, value in ENV.items() if key not in ("PYTHONPATH", "VIRTUAL_ENV", "PYTHONHOME")}
    env["PATH"] = f"{venv / 'bin'}{os.pathsep}/usr/bin{os.pathsep}/bin"
    env["VIRTUAL_ENV"] = str(venv)
    if prefix is not None:
        env["PYTHONPATH"] = str(next(prefix.glob("lib/python3*/site-packages")))
        env["AMENT_PREFIX_PATH"] = str(prefix)
    return env


USES_EVERY_DEPENDENCY = """
import importlib, pkgutil, sys
import frisicp_core, frisicp_ros
for package in (frisicp_core, frisicp_ros):
    for module in pkgutil.walk_packages(package.__path__, package.__name__ + "."):
        importlib.import_module(module.name)
from frisicp_core.kdtree import NearestNeighbors
from frisicp_core.io import read_points
import numpy as np
assert NearestNeighbors(np.eye(3), "pykdtree").backend == "pykdtree"
assert read_points(sys.argv[1]).shape == read_points(sys.argv[2]).shape == (50, 3)
assert not any(name.startswith("frisicp_bench") for name in sys.modules)
print("every dependency is there")
"""


@pytest.fixture
def diagnostics():
    with spinning_node("clean_probe", DOMAIN) as probe:
        received: list[DiagnosticArray] = []
        probe.create_subscription(DiagnosticArray, "/diagnostics", received.append, 10)
        yield received


def test_built_with_only_package_xml_dependencies_the_node_starts_answers_and_stops(tmp_path, diagnostics):
    venv = clean_venv()
    source = tmp_path / "src" / "frisicp_ros"
    shutil.copytree(
        ROOT,
        source,
        ignore=shutil.ignore_patterns(
            ".venv", "build", "install", "log", ".git", "__pycache__", "*.egg-info"
        ),
    )
    build = subprocess.run(
        [str(venv / "bin" / "colcon"), "build"],
        cwd=tmp_path,
        env=clean_environment(venv),
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert build.returncode == 0, build.stdout[-3000:] + build.stderr[-3000:]
    prefix = tmp_path / "install" / "frisicp_ros"
    env = clean_environment(venv, prefix)

    ply, pcd = tmp_path / "cloud.ply", tmp_path / "cloud.pcd"
    write_ply_and_pcd(np.random.default_rng(0).normal(size=(50, 3)), ply, pcd)
    uses = subprocess.run(
        [str(venv / "bin" / "python"), "-c", USES_EVERY_DEPENDENCY, str(ply), str(pcd)],
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert uses.returncode == 0, uses.stderr[-3000:]

    node = subprocess.Popen(
        [
            str(prefix / "lib" / "frisicp_ros" / "register_node"),
            "--ros-args",
            "-p",
            "diagnostics_period:=0.2",
        ],
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        answered = wait_until(
            lambda: any(s.name == "frisicp: registration" for a in diagnostics for s in a.status), 30.0
        )
        assert answered, "no /diagnostics from the installed node: " + (
            node.communicate(timeout=5)[1] if node.poll() is not None else "(running)"
        )
        node.send_signal(signal.SIGINT)
        _, stderr = node.communicate(timeout=20)
        assert node.returncode == 0 and "Traceback" not in stderr, stderr
    finally:
        if node.poll() is None:
            node.kill()
            node.wait(5)


def write_ply_and_pcd(points: np.ndarray, ply: Path, pcd: Path) -> None:
    header = "ply\nformat ascii 1.0\nelement vertex 50\nproperty float x\nproperty float y\nproperty float z\nend_header\n"
    ply.write_text(header + "".join(f"{x} {y} {z}\n" for x, y, z in points))
    pcd.write_text(
        "# .PCD v0.7\nVERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 50\nHEIGHT 1\n"
        "VIEWPOINT 0 0 0 1 0 0 0\nPOINTS 50\nDATA ascii\n" + "".join(f"{x} {y} {z}\n" for x, y, z in points)
    )
