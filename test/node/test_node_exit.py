"""A node process whose context is shut down from inside (``bag_exit_on_end`` does so from the
replay thread when the bag is done) exits 0, also when a callback is publishing at that moment.

Domain 141 (unique to this module), loopback discovery only. CI once caught the race in
test_node_replay.py: the diagnostics timer published as the replay thread shut the context
down, rclpy raised RCLError ("publisher's context is invalid") out of spin, and the process
ended with a traceback and code 1 after every pair had been published.
"""

from __future__ import annotations

import subprocess
import sys

import pytest
from support.ros import ros_environment

DOMAIN = 141
ENV = ros_environment(DOMAIN)

pytestmark = pytest.mark.ros

# A node whose timer shuts its context down and then publishes, as the replay thread and the
# diagnostics timer can do together, run as register_node runs its node.
RACING_NODE = """
import sys
from rclpy.node import Node
from std_msgs.msg import Empty
from frisicp_ros.node.node import run_node_process


class Racing(Node):
    def __init__(self):
        super().__init__("frisicp_exit_race")
        self.out = self.create_publisher(Empty, "~/out", 1)
        self.create_timer(0.05, self.tick)

    def tick(self):
        self.context.try_shutdown()
        self.out.publish(Empty())


sys.exit(run_node_process(Racing))
"""


def test_a_callback_publishing_as_the_context_shuts_down_ends_the_process_with_code_0() -> None:
    done = subprocess.run(
        [sys.executable, "-c", RACING_NODE], env=ENV, capture_output=True, text=True, timeout=60
    )
    assert done.returncode == 0, done.stderr
    assert "Traceback" not in done.stderr
