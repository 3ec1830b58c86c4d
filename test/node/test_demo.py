"""The demo's data stream (frisicp-demo): what it shows must be what the core gets right."""

import numpy as np
import pytest

from frisicp_core import bumpy_surface, register, rotation_angle
from frisicp_ros.node.demo import truth_at


def test_noisy_resampled_cold_starts_never_pick_a_flipped_pose():
    """Regression: the live demo's stream (a fresh noisy sample of the surface per frame, scale
    0.7-1.3, up to 25 deg) once got 180-degree flips when hypotheses were screened on too few points."""
    model = bumpy_surface(20000, seed=0)
    rng = np.random.default_rng(7)
    for k in range(10):
        truth = truth_at(0.5 * k)
        sample = bumpy_surface(5000, seed=int(rng.integers(1 << 30)))
        data = truth.inverse().apply(sample) + rng.normal(scale=0.005, size=sample.shape)
        estimate = register(data, model).similarity
        assert np.rad2deg(rotation_angle(estimate.rotation.T @ truth.rotation)) < 1.0, f"t = {0.5 * k}"


def test_the_demo_keeps_a_domain_the_user_set_and_has_its_own_otherwise():
    from frisicp_ros.node.demo import DEFAULT_DOMAIN_ID, domain_id

    assert domain_id(None, {"ROS_DOMAIN_ID": "77"}) == 77
    assert domain_id(None, {}) == domain_id(None, {"ROS_DOMAIN_ID": ""}) == DEFAULT_DOMAIN_ID
    assert domain_id(5, {"ROS_DOMAIN_ID": "77"}) == 5  # --domain-id says it explicitly


def test_the_demo_finds_register_node_beside_itself_as_in_a_colcon_workspace(tmp_path, monkeypatch):
    """`ros2 run frisicp_ros frisicp-demo` runs <prefix>/lib/frisicp_ros/frisicp-demo, with
    register_node beside it and neither on PATH nor beside the interpreter."""
    from frisicp_ros.node import demo

    lib = tmp_path / "install" / "frisicp_ros" / "lib" / "frisicp_ros"
    lib.mkdir(parents=True)
    for name in ("frisicp-demo", "register_node"):
        (lib / name).write_text("#!/bin/sh\n")
        (lib / name).chmod(0o755)
    monkeypatch.setattr(demo.sys, "argv", [str(lib / "frisicp-demo")])
    monkeypatch.setattr(demo.sys, "executable", str(tmp_path / "python3"))
    monkeypatch.setenv("PATH", str(tmp_path / "empty"))
    monkeypatch.delenv("AMENT_PREFIX_PATH", raising=False)
    assert demo.register_node_script() == str(lib / "register_node")
    (lib / "register_node").unlink()
    with pytest.raises(SystemExit, match="register_node is not installed"):
        demo.register_node_script()
