"""``register_lifecycle_node``: the same node as a managed (lifecycle) node.

The parameters are declared at construction (so they can be set and described while
unconfigured) and read at **configure**, which builds the pipeline, publishers, subscriptions,
``~/reset`` and ``~/initial_guess``; a bad value fails the transition with its reason (logged).
**activate** starts registering and enables every publisher; **deactivate** stops the worker
(waiting for a running registration) and disables them: no output at all while inactive, not
even /diagnostics. While inactive the model subscription still keeps the newest (latched) model,
so activating again needs no republished map; data clouds are not taken. **cleanup** destroys
what configure built, **shutdown** does the same from any state. Transitions come from a
lifecycle manager (Nav2's) or the standard services ``~/change_state`` and ``~/get_state``.
"""

from __future__ import annotations

import os

os.environ.setdefault("OMP_NUM_THREADS", "1")  # as register_node, before pykdtree loads

import sys
from collections.abc import Callable
from typing import Any

from rclpy.lifecycle import LifecycleNode, LifecycleState, TransitionCallbackReturn
from rclpy.parameter import Parameter

from frisicp_ros.node import parameters
from frisicp_ros.node.node import NODE_NAME, RegistrationParts, run_node_process
from frisicp_ros.stream.pipeline import describe


class RegistrationLifecycleNode(RegistrationParts, LifecycleNode):
    def __init__(self, **kwargs: Any) -> None:
        super().__init__(NODE_NAME, **kwargs)
        parameters.declare(self)
        self.add_on_set_parameters_callback(self._validate_parameters)
        self.add_post_set_parameters_callback(self._apply_parameters)
        self._configured = False

    def _transition(self, name: str, step: Callable[[], None]) -> TransitionCallbackReturn:
        """Run ``step``; a failure is logged with its reason (rclpy would swallow it)."""
        try:
            step()
        except Exception as err:  # noqa: BLE001 - a transition fails with its reason, never silently
            self.get_logger().error(f"{name} failed: {describe(err)}")
            return TransitionCallbackReturn.FAILURE
        return TransitionCallbackReturn.SUCCESS

    def on_configure(self, state: LifecycleState) -> TransitionCallbackReturn:
        def configure() -> None:
            self.set_up(self.create_lifecycle_publisher, parameters.current_values(self))
            self._configured = True

        return self._transition("configure", configure)

    def on_activate(self, state: LifecycleState) -> TransitionCallbackReturn:
        enabled = super().on_activate(state)  # the lifecycle publishers, before the first output
        if enabled != TransitionCallbackReturn.SUCCESS:
            return enabled
        return self._transition("activate", self.start_work)

    def on_deactivate(self, state: LifecycleState) -> TransitionCallbackReturn:
        result = self._transition("deactivate", self.stop_work)
        if result != TransitionCallbackReturn.SUCCESS:
            return result
        return super().on_deactivate(state)

    def on_cleanup(self, state: LifecycleState) -> TransitionCallbackReturn:
        return self._transition("cleanup", self._clean_up)

    def on_shutdown(self, state: LifecycleState) -> TransitionCallbackReturn:
        return self._transition("shutdown", self._clean_up)

    def _clean_up(self) -> None:
        if self._configured:
            self.stop_work()
            self.tear_down(self.destroy_lifecycle_publisher)
            self._configured = False

    def _apply_parameters(self, changes: list[Parameter]) -> None:
        if self._configured:  # else they are read at configure
            super()._apply_parameters(changes)

    def destroy_node(self) -> None:
        if self._configured:
            self.stop_work()
        super().destroy_node()


def main(args: list[str] | None = None) -> int:
    """Console script ``register_lifecycle_node``: starts unconfigured; stops as register_node
    does (``run_node_process``)."""
    return run_node_process(RegistrationLifecycleNode, args)


if __name__ == "__main__":
    sys.exit(main())
