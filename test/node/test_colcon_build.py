"""`colcon build` of the package in a temporary workspace: the layout `ros2 run`/`ros2 launch` use.

``ros2``/``launch`` are not installable here, so the closest real checks are made: the installed
``register_node`` script runs (and exits with its parameter error, proving it imports the
installed node), ament_index_python finds the package's share directory the way the launch file
does, and the launch file compiles and names that executable, config file and arguments.
"""

from __future__ import annotations

import ast
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.ros

ROOT = Path(__file__).resolve().parents[2]
PACKAGE_FILES = (
    "package.xml",
    "setup.py",
    "setup.cfg",
    "README.md",
    "resource",
    "frisicp_core",
    "frisicp_ros",
    "frisicp_bench",
    "config",
    "launch",
)
DOMAIN_ID = "133"  # unique to this module; the installed node is started once (and fails early)


def build(workspace: Path, *options: str) -> Path:
    source = workspace / "src" / "frisicp_ros"
    source.mkdir(parents=True)
    for name in PACKAGE_FILES:
        path = ROOT / name
        if path.is_dir():
            shutil.copytree(path, source / name, ignore=shutil.ignore_patterns("__pycache__", "*.egg-info"))
        else:
            shutil.copy2(path, source / name)
    env = dict(os.environ, PATH=f"{Path(sys.executable).parent}{os.pathsep}{os.environ['PATH']}")
    run = subprocess.run(
        [str(Path(sys.executable).parent / "colcon"), "build", *options],
        cwd=workspace,
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert run.returncode == 0, run.stdout + run.stderr
    return workspace / "install" / "frisicp_ros"


@pytest.mark.parametrize("options", [(), ("--symlink-install",)], ids=["install", "symlink-install"])
def test_colcon_build_installs_what_ros2_run_and_launch_need(tmp_path, options):
    prefix = build(tmp_path, *options)
    share = prefix / "share" / "frisicp_ros"
    register_node = prefix / "lib" / "frisicp_ros" / "register_node"
    assert os.access(register_node, os.X_OK)
    assert (prefix / "share" / "ament_index" / "resource_index" / "packages" / "frisicp_ros").exists()
    for relative in ("package.xml", "config/frisicp.yaml", "launch/register.launch.py"):
        assert (share / relative).is_file(), relative
    assert (share / "config" / "frisicp.yaml").read_text() == (ROOT / "config" / "frisicp.yaml").read_text()

    site_packages = next(prefix.glob("lib/python3*/site-packages"))
    env = dict(
        os.environ,
        AMENT_PREFIX_PATH=str(prefix),
        PYTHONPATH=str(site_packages),
        ROS_DOMAIN_ID=DOMAIN_ID,
        ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST",
    )
    found = subprocess.run(
        [
            sys.executable,
            "-c",
            "from ament_index_python.packages import get_package_share_directory as g;"
            " print(g('frisicp_ros'))",
        ],
        env=env,
        capture_output=True,
        text=True,
        timeout=30,
    )
    assert Path(found.stdout.strip()).resolve() == share.resolve(), found.stderr
    run = subprocess.run(
        [str(register_node), "--ros-args", "-p", "method:=ransac"],
        env=env,
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert run.returncode == 2 and "method must be one of" in run.stderr, run.stderr


def test_launch_file_starts_register_node_with_the_config_and_topic_arguments():
    source = (ROOT / "launch" / "register.launch.py").read_text()
    tree = ast.parse(source)  # compiles: a syntax error fails here
    strings = {
        node.value
        for node in ast.walk(tree)
        if isinstance(node, ast.Constant) and isinstance(node.value, str)
    }
    assert {
        "register_node",
        "frisicp_ros",
        "frisicp.yaml",
        "model_topic",
        "data_topic",
        "model",
        "data",
    } <= strings
    assert any(isinstance(n, ast.FunctionDef) and n.name == "generate_launch_description" for n in tree.body)
    assert "register_node = frisicp_ros.node.node:main" in (ROOT / "setup.py").read_text()
