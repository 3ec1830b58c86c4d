"""The packages import only downward: cli / node -> bag -> stream -> frisicp_core; no ROS below the node."""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
ROS = (
    "rclpy",
    "rcl_interfaces",
    "sensor_msgs",
    "geometry_msgs",
    "std_msgs",
    "std_srvs",
    "diagnostic_msgs",
    "lifecycle_msgs",
    "tf2_msgs",
)
# What each layer must not import, anywhere in it (also inside functions).
FORBIDDEN = {
    "frisicp_core": ("frisicp_ros", "frisicp_bench", "rosbags", *ROS),
    "frisicp_bench": ("frisicp_ros", "rosbags", *ROS),
    # importlib: a message package looked up by name is a ROS import this test would not see
    "frisicp_ros/stream": ("frisicp_ros.bag", "frisicp_ros.node", "frisicp_ros.cli", "importlib", *ROS),
    "frisicp_ros/bag": ("frisicp_ros.node", "frisicp_ros.cli", *ROS),
    "frisicp_ros/cli": ("frisicp_ros.node", *ROS),
    "frisicp_ros/node": ("frisicp_ros.cli",),
}


def imported(path: Path, top_level_only: bool = False) -> set[str]:
    tree = ast.parse(path.read_text())
    nodes = tree.body if top_level_only else list(ast.walk(tree))
    names: set[str] = set()
    for node in nodes:
        if isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            names.add(node.module)
    return names


def offending(names: set[str], forbidden: tuple[str, ...]) -> list[str]:
    return sorted(n for n in names if any(n == f or n.startswith(f + ".") for f in forbidden))


@pytest.mark.parametrize("layer", FORBIDDEN)
def test_a_layer_imports_nothing_above_it(layer):
    files = sorted((ROOT / layer).glob("*.py"))
    assert files
    for path in files:
        assert not offending(imported(path), FORBIDDEN[layer]), path.relative_to(ROOT)


def test_packages_import_each_other_by_absolute_name():
    """Relative imports would hide a wrong-way import from the check above."""
    for path in sorted(ROOT.glob("frisicp_*/**/*.py")):
        tree = ast.parse(path.read_text())
        relative = [n for n in ast.walk(tree) if isinstance(n, ast.ImportFrom) and n.level > 0]
        in_core = path.parent.name in ("frisicp_core", "frisicp_bench")  # flat packages: siblings only
        assert in_core or not relative, path.relative_to(ROOT)


def test_the_live_node_loads_no_bag_code():
    """`ros2 run` without a bag must not need rosbags: the replay is imported only when replaying."""
    names = imported(ROOT / "frisicp_ros" / "node" / "node.py", top_level_only=True)
    assert not offending(names, ("frisicp_ros.bag", "frisicp_ros.node.replay", "rosbags"))


def test_the_readme_architecture_table_lists_every_module_of_each_layer():
    """README's "Architecture" table names each layer's modules: exactly those in the folder."""
    readme = (ROOT / "README.md").read_text()
    table = readme.split("## Architecture", 1)[1].split("\n## ", 1)[0]
    rows = {}
    for line in table.splitlines():
        cells = [cell.strip() for cell in line.split("|")[1:-1]]
        if len(cells) == 3 and cells[0].startswith("`"):
            layer = cells[0].split("`")[1]
            rows[layer] = set(re.findall(r"`(\w+)`", cells[1]))
    assert set(rows) == {*(layer.replace("/", ".") for layer in FORBIDDEN), "benchmarks/"}
    for layer, listed in rows.items():
        folder = ROOT / layer.replace(".", "/")
        actual = {path.stem for path in folder.glob("*.py") if path.stem != "__init__"}
        assert listed == actual, (
            f"{layer}: README lists {sorted(listed - actual)} not there, misses {sorted(actual - listed)}"
        )
