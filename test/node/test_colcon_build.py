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
    for script in ("register_node", "register_lifecycle_node", "frisicp-demo", "frisicp"):
        assert os.access(prefix / "lib" / "frisicp_ros" / script, os.X_OK), script
    assert (prefix / "share" / "ament_index" / "resource_index" / "packages" / "frisicp_ros").exists()
    for relative in (
        "package.xml",
        "config/frisicp.yaml",
        "config/frisicp.rviz",
        "config/fastdds_large_messages.xml",
        "launch/register.launch.py",
    ):
        assert (share / relative).is_file(), relative
    assert (share / "config" / "frisicp.yaml").read_text() == (ROOT / "config" / "frisicp.yaml").read_text()

    env = dict(
        os.environ,
        AMENT_PREFIX_PATH=str(prefix),
        PYTHONPATH=sourced_pythonpath(prefix),
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


def test_ros2_run_frisicp_demo_works_in_a_workspace_and_keeps_the_users_domain(tmp_path):
    """What `ros2 run frisicp_ros frisicp-demo` runs: lib/frisicp_ros/frisicp-demo, with the
    workspace sourced (PYTHONPATH, AMENT_PREFIX_PATH) and register_node only beside it."""
    prefix = build(tmp_path)
    env = dict(
        os.environ,
        AMENT_PREFIX_PATH=str(prefix),
        PYTHONPATH=sourced_pythonpath(prefix),
        PATH=f"/usr/bin{os.pathsep}/bin",  # neither the venv's bin nor the workspace's lib on PATH
        ROS_DOMAIN_ID=DOMAIN_ID,
        ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST",
    )
    picture = tmp_path / "last.png"
    demo = subprocess.run(
        [str(prefix / "lib" / "frisicp_ros" / "frisicp-demo"), "--duration", "2", "--plot", str(picture)],
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert demo.returncode == 0, demo.stdout[-2000:] + demo.stderr[-2000:]
    assert f"ROS domain {DOMAIN_ID}" in demo.stdout
    assert "register_node stopped cleanly" in demo.stdout
    assert picture.stat().st_size > 10_000


def sourced_pythonpath(prefix: Path) -> str:
    """PYTHONPATH as sourcing the workspace sets it: the package's environment hooks (share/<pkg>/
    package.dsv and the files it sources; a --symlink-install adds the build folder)."""
    entries: list[str] = []

    def read(dsv: Path) -> None:
        for line in dsv.read_text().splitlines():
            kind, _, rest = line.partition(";")
            if kind == "source" and rest.endswith(".dsv"):
                read((prefix / rest).resolve() if not Path(rest).is_absolute() else Path(rest))
            elif kind == "prepend-non-duplicate" and rest.startswith("PYTHONPATH;"):
                path = rest.split(";", 1)[1]
                entries.insert(0, path if Path(path).is_absolute() else str(prefix / path))

    read(prefix / "share" / "frisicp_ros" / "package.dsv")
    return os.pathsep.join(entries)


class _Recorded:
    """A stand-in for a launch class: records how it was constructed."""

    def __init__(self, *args, **kwargs):
        self.args, self.kwargs = args, kwargs


class _Node(_Recorded):
    pass


class _LifecycleNode(_Recorded):
    pass


class _LaunchConfiguration(_Recorded):
    def perform(self, context):
        return context[self.args[0]]


def _fake_launch_modules(monkeypatch):
    """``launch`` and ``launch_ros`` are not on PyPI: modules with the few names the file uses."""
    import types

    modules = {
        "launch": {"LaunchDescription": _Recorded},
        "launch.actions": {"DeclareLaunchArgument": _Recorded, "OpaqueFunction": _Recorded},
        "launch.substitutions": {"LaunchConfiguration": _LaunchConfiguration},
        "launch_ros": {},
        "launch_ros.actions": {"Node": _Node, "LifecycleNode": _LifecycleNode},
    }
    for name, members in modules.items():
        module = types.ModuleType(name)
        module.__dict__.update(members)
        monkeypatch.setitem(sys.modules, name, module)


def _launch(monkeypatch, environ=None, **given: str):
    """Run the launch file as ``ros2 launch`` would: declared defaults, then ``given``; returns
    the declared arguments and the Node's constructor arguments."""
    import runpy

    _fake_launch_modules(monkeypatch)
    monkeypatch.setattr(
        "ament_index_python.packages.get_package_share_directory", lambda package: f"/share/{package}"
    )
    if environ is not None:
        monkeypatch.setattr(os, "environ", environ)
    namespace = runpy.run_path(str(ROOT / "launch" / "register.launch.py"))
    description = namespace["generate_launch_description"]()
    actions = description.args[0]
    declared = {a.args[0]: a.kwargs for a in actions if type(a).__name__ == "_Recorded" and a.args}
    context = {name: spec["default_value"] for name, spec in declared.items()} | given
    for name, value in given.items():
        choices = declared[name].get("choices")
        assert choices is None or value in choices, (name, value, choices)
    (opaque,) = [a for a in actions if "function" in a.kwargs]
    (node,) = opaque.kwargs["function"](context)

    def resolved(value):
        return value.perform(context) if isinstance(value, _LaunchConfiguration) else value

    arguments = dict(node.kwargs, node_class=type(node).__name__)
    arguments["name"], arguments["namespace"] = (
        resolved(node.kwargs["name"]),
        resolved(node.kwargs["namespace"]),
    )
    arguments["parameters"] = [resolved(p) for p in node.kwargs["parameters"]]
    arguments["arguments"] = [resolved(a) for a in node.kwargs["arguments"]]
    arguments["remappings"] = [(k, resolved(v)) for k, v in node.kwargs["remappings"]]
    return declared, arguments


def test_launch_arguments_set_namespace_name_log_level_and_qos(monkeypatch):
    from frisicp_ros.stream.settings import DATA_QOS_CHOICES, MODEL_QOS_CHOICES

    declared, node = _launch(monkeypatch)
    assert node["package"] == "frisicp_ros" and node["executable"] == "register_node"
    assert (node["name"], node["namespace"]) == ("frisicp", "")
    assert node["parameters"] == ["/share/frisicp_ros/config/frisicp.yaml"]  # the file's QoS stays
    assert node["arguments"] == ["--ros-args", "--log-level", "frisicp:=info"]  # the node's logger only
    assert node["remappings"] == [("model", "model"), ("data", "data")]
    assert declared["model_qos"]["choices"] == ["", *MODEL_QOS_CHOICES]  # the settings table's
    assert declared["data_qos"]["choices"] == ["", *DATA_QOS_CHOICES]

    _, node = _launch(
        monkeypatch,
        namespace="robot1",
        node_name="align",
        log_level="debug",
        model_qos="transient_local",
        params_file="/my.yaml",
        model_topic="/map",
        data_topic="/points",
    )
    assert (node["name"], node["namespace"]) == ("align", "robot1")
    assert node["parameters"] == ["/my.yaml", {"model_qos": "transient_local"}]
    assert node["arguments"] == ["--ros-args", "--log-level", "robot1.align:=debug"]
    assert node["remappings"] == [("model", "/map"), ("data", "/points")]


def test_launch_lifecycle_argument_starts_the_managed_node(monkeypatch):
    _, plain = _launch(monkeypatch)
    assert (plain["node_class"], plain["executable"]) == ("_Node", "register_node")
    _, managed = _launch(monkeypatch, lifecycle="true", namespace="/robot1/")
    assert (managed["node_class"], managed["executable"]) == ("_LifecycleNode", "register_lifecycle_node")
    assert managed["arguments"] == ["--ros-args", "--log-level", "robot1.frisicp:=info"]
    assert "register_lifecycle_node = frisicp_ros.node.lifecycle:main" in (ROOT / "setup.py").read_text()


PROFILE = "/share/frisicp_ros/config/fastdds_large_messages.xml"


@pytest.mark.parametrize(
    ("environ", "choice", "expected"),
    [
        ({"ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"}, "auto", PROFILE),  # all on this machine
        ({}, "auto", None),  # other machines may publish: shared memory only would cut them off
        (
            {"ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST", "RMW_IMPLEMENTATION": "rmw_cyclonedds_cpp"},
            "auto",
            None,
        ),
        (
            {"ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST", "FASTRTPS_DEFAULT_PROFILES_FILE": "/mine.xml"},
            "auto",
            None,
        ),
        ({}, "true", PROFILE),
        ({"FASTRTPS_DEFAULT_PROFILES_FILE": "/mine.xml"}, "true", None),  # the user's own wins
        ({"ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"}, "false", None),
    ],
)
def test_large_messages_profile_is_used_where_it_helps(monkeypatch, environ, choice, expected):
    declared, node = _launch(monkeypatch, environ=environ, large_messages_profile=choice)
    assert declared["large_messages_profile"]["default_value"] == "auto"
    env = node["additional_env"] or {}
    assert env.get("FASTRTPS_DEFAULT_PROFILES_FILE") == expected
    assert (ROOT / "config" / "fastdds_large_messages.xml").is_file()


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
