"""The node's ROS parameters: one table of names, descriptions and ranges.

Defaults come from :class:`PipelineSettings` (the pipeline's options) and ``NODE_DEFAULTS``
(options only the live node has); ``config/frisicp.yaml`` repeats them for users and a test keeps
the two in step. Validation of a change builds a new PipelineSettings, which builds a
``RegistrationConfig``: the core's own checks are the reasons a user sees.
"""

from __future__ import annotations

from dataclasses import dataclass, fields
from typing import Any

from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor
from rclpy.node import Node
from rclpy.parameter import Parameter

from frisicp_core import Initialization, Method
from frisicp_ros.stream.pairing import PAIRING_MODES
from frisicp_ros.stream.pipeline import PipelineSettings

MODEL_QOS_CHOICES = ("sensor_data", "reliable", "transient_local")
DATA_QOS_CHOICES = ("sensor_data", "reliable")


@dataclass(frozen=True)
class ParameterSpec:
    description: str
    int_range: tuple[int, int] | None = None
    float_range: tuple[float, float] | None = None
    choices: tuple[str, ...] | None = None
    read_only: bool = False  # QoS: subscriptions are made once, at start-up


SPECS: dict[str, ParameterSpec] = {
    # node options
    "model_qos": ParameterSpec(
        "QoS of the model subscription: sensor_data (best effort, depth 5), reliable (depth 5), or "
        "transient_local (reliable, transient local, depth 1: a latched map)",
        choices=MODEL_QOS_CHOICES,
        read_only=True,
    ),
    "data_qos": ParameterSpec(
        "QoS of the data subscription: sensor_data or reliable (depth 5)",
        choices=DATA_QOS_CHOICES,
        read_only=True,
    ),
    "diagnostics_period": ParameterSpec(
        "seconds between /diagnostics messages", float_range=(0.1, 60.0), read_only=True
    ),
    "pairing": ParameterSpec(
        "latest_model: each data cloud against the newest model (map-to-scan); synchronized: pairs"
        " by header stamp within sync_tolerance (two sensors)",
        choices=PAIRING_MODES,
    ),
    "sync_tolerance": ParameterSpec(
        "largest stamp difference (s) of a synchronized pair", float_range=(0.0, 10.0)
    ),
    "dims": ParameterSpec("2: register x y only (planar scans); 3: x y z", int_range=(2, 3)),
    "max_points": ParameterSpec(
        "cap on points per cloud (random subset above it) to bound latency; 0 = no cap",
        int_range=(0, 100_000_000),
    ),
    "warm_start": ParameterSpec("start each registration from the previous converged estimate"),
    "model_frame": ParameterSpec("expected frame id of model clouds; empty = accept any"),
    "data_frame": ParameterSpec("expected frame id of data clouds; empty = accept any"),
    "publish_aligned": ParameterSpec(
        "publish ~/aligned (data cloud in the model frame) when it has subscribers"
    ),
    # algorithm options (frisicp_core.RegistrationConfig / ConvergenceCriteria)
    "method": ParameterSpec(
        "algorithm: frisicp (bidirectional, free scale), icp (s = 1), scale-icp, bounded-icp",
        choices=tuple(m.value for m in Method),
    ),
    "levels": ParameterSpec("sparse-to-dense levels", int_range=(1, 10)),
    "coarsest_points": ParameterSpec("points on the coarsest level", int_range=(10, 10_000_000)),
    "max_iterations": ParameterSpec("iteration cap per level", int_range=(1, 100_000)),
    "relative_motion": ParameterSpec(
        "convergence: motion between iterations relative to the model's RMS radius (finest level)",
        float_range=(0.0, 1.0),
    ),
    "relative_rmse": ParameterSpec(
        "convergence: relative change of the error between iterations", float_range=(0.0, 1.0)
    ),
    "coarse_relative_motion": ParameterSpec(
        "convergence motion threshold on the coarse levels", float_range=(0.0, 1.0)
    ),
    "overlap": ParameterSpec(
        "fraction (0, 1] of closest correspondences kept (trimming); 1 = all", float_range=(0.0, 1.0)
    ),
    "max_distance": ParameterSpec(
        "drop correspondences farther than this many times the median distance; 0 = keep all",
        float_range=(0.0, 1e6),
    ),
    "initialization": ParameterSpec(
        "start without warm start: identity, moments, principal-axes",
        choices=tuple(i.value for i in Initialization),
    ),
    "acceleration": ParameterSpec(
        "Anderson acceleration of the iterations (kept only when it lowers the error)"
    ),
    "seed": ParameterSpec("seed of the random down-sampling", int_range=(0, 2**31 - 1)),
    "backend": ParameterSpec("KD-tree library: auto, pykdtree, scipy", choices=("auto", "pykdtree", "scipy")),
}
NODE_DEFAULTS: dict[str, Any] = {
    "model_qos": "sensor_data",
    "data_qos": "sensor_data",
    "diagnostics_period": 1.0,
}


def defaults() -> dict[str, Any]:
    """Every parameter's default value, by name."""
    values = {f.name: f.default for f in fields(PipelineSettings)}
    values.update(NODE_DEFAULTS)
    return values


def descriptor(name: str, spec: ParameterSpec) -> ParameterDescriptor:
    desc = ParameterDescriptor(name=name, description=spec.description, read_only=spec.read_only)
    if spec.int_range:
        desc.integer_range = [IntegerRange(from_value=spec.int_range[0], to_value=spec.int_range[1], step=1)]
    if spec.float_range:
        desc.floating_point_range = [
            FloatingPointRange(from_value=spec.float_range[0], to_value=spec.float_range[1], step=0.0)
        ]
    if spec.choices:
        desc.additional_constraints = "one of: " + ", ".join(spec.choices)
    return desc


def declare(node: Node) -> None:
    """Declare every parameter (values from --params-file / -p override the defaults)."""
    values = defaults()
    assert set(values) == set(SPECS), "every parameter needs a spec"  # a programming error
    for name, spec in SPECS.items():
        node.declare_parameter(name, values[name], descriptor(name, spec))


def settings_from(values: dict[str, Any]) -> PipelineSettings:
    """PipelineSettings from parameter values; ValueError (with the reason) if any is invalid."""
    for name, value in values.items():
        choices = SPECS[name].choices
        if choices and value not in choices:
            raise ValueError(f"{name} must be one of {', '.join(choices)}, got {value!r}")
    pipeline_names = PipelineSettings.names()
    return PipelineSettings(**{k: v for k, v in values.items() if k in pipeline_names})


def current_values(node: Node) -> dict[str, Any]:
    return {name: node.get_parameter(name).value for name in SPECS}


def with_changes(node: Node, changes: list[Parameter]) -> dict[str, Any]:
    values = current_values(node)
    values.update({p.name: p.value for p in changes if p.name in SPECS})
    return values
