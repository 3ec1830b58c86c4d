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
import signal
import subprocess
from pathlib import Path

import numpy as np
import pytest
from support.ros import ros_environment, spinning_node, wait_until
from support.workspace import (
    RUNTIME_AND_TESTS,
    clean_environment,
    clean_venv,
    copy_source,
    declared,
    requirements,
)

DOMAIN = 137
ENV = ros_environment(DOMAIN)

from diagnostic_msgs.msg import DiagnosticArray  # noqa: E402

pytestmark = [pytest.mark.ros, pytest.mark.slow]

ROOT = Path(__file__).resolve().parents[2]


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


USES_EVERY_DEPENDENCY = """
import importlib, pkgutil, sys
import frisicp_core, frisicp_ros
# `frisicp bag --scheduler` needs the dask extra, which package.xml does not declare (the command
# says so when it is missing): that module alone may lack exactly that package.
OPTIONAL = {"frisicp_ros.bag.cluster": "distributed"}
for package in (frisicp_core, frisicp_ros):
    for module in pkgutil.walk_packages(package.__path__, package.__name__ + "."):
        try:
            importlib.import_module(module.name)
        except ModuleNotFoundError as err:
            if OPTIONAL.get(module.name) != err.name:
                raise
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


def test_every_test_dependency_is_declared_and_resolvable():
    """`colcon test` needs them in the workspace: what test/ imports or runs, as test_depend keys."""
    keys = declared(RUNTIME_AND_TESTS)
    for key in (
        "python3-pytest",
        "python3-yaml",
        "python3-mcap-ros2-support-pip",
        "python3-threadpoolctl-pip",
        "python3-distributed-pip",
    ):
        assert key in keys, key
    assert {"mcap-ros2-support", "threadpoolctl", "distributed", "pyyaml", "pillow", "pytest"} <= set(
        requirements(RUNTIME_AND_TESTS)
    )


def test_built_with_only_package_xml_dependencies_the_node_starts_answers_and_stops(tmp_path, diagnostics):
    venv = clean_venv()
    copy_source(tmp_path)
    build = subprocess.run(
        [str(venv / "bin" / "colcon"), "build"],
        cwd=tmp_path,
        env=clean_environment(venv, ENV),
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert build.returncode == 0, build.stdout[-3000:] + build.stderr[-3000:]
    prefix = tmp_path / "install" / "frisicp_ros"
    env = clean_environment(venv, ENV, prefix)

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
