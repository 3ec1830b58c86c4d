"""The node's ROS parameters, declared from the settings table (``frisicp_ros.stream.settings``).

Every NODE option becomes a parameter with the table's default, description, range or choices
and read-only flag. Validation of a change goes through ``settings_from`` (the table's checks,
then the core's): the reasons a user sees are those of the table and of ``RegistrationConfig``.
"""

from __future__ import annotations

from typing import Protocol

from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor
from rclpy.node import Node
from rclpy.parameter import Parameter

from frisicp_ros.stream.settings import Option, Surface, Value, options_for

NODE_OPTIONS = options_for(Surface.NODE)


class HasParameters(Protocol):
    """A node, plain or managed: what reading the parameters needs."""

    def get_parameter(self, name: str) -> Parameter: ...


NAMES = frozenset(o.name for o in NODE_OPTIONS)


def descriptor(option: Option) -> ParameterDescriptor:
    desc = ParameterDescriptor(name=option.name, description=option.description, read_only=option.read_only)
    if option.bounds is not None and option.kind is int:
        low, high = (int(bound) for bound in option.bounds)
        desc.integer_range = [IntegerRange(from_value=low, to_value=high, step=1)]
    elif option.bounds is not None:
        low_f, high_f = (float(bound) for bound in option.bounds)
        desc.floating_point_range = [FloatingPointRange(from_value=low_f, to_value=high_f, step=0.0)]
    if option.choices:
        desc.additional_constraints = "one of: " + ", ".join(option.choices)
    if option.rule is not None:
        desc.additional_constraints = option.rule.text
    return desc


def declare(node: Node) -> None:
    """Declare every parameter (values from --params-file / -p override the defaults)."""
    for option in NODE_OPTIONS:
        node.declare_parameter(option.name, option.default, descriptor(option))


def current_values(node: HasParameters) -> dict[str, Value]:
    return {name: node.get_parameter(name).value for name in NAMES}


def with_changes(node: HasParameters, changes: list[Parameter]) -> dict[str, Value]:
    values = current_values(node)
    values.update({p.name: p.value for p in changes if p.name in NAMES})
    return values
