"""Viewer node: the run live in Foxglove (``ws://localhost:8765``, "Open connection").

Wiring around :class:`~pdsmc_ros.live_view.LiveView` and its Foxglove server: the
node takes the loop's states and commands as an observer (best-effort subscriptions,
never waited for: it cannot slow the loop) and, at ``display_rate`` frames per second
of wall time, streams the newest state -- the arm's link transforms, its URDF, the
desired path (the run's references, computed as the trajectory node does) and the
actual one, the joint errors, contour error and torques (``live_view.CHANNELS``).
Lockstep or real time alike. It ends when the plant leaves the graph, or on Ctrl-C.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Sequence

from rclpy.node import Node
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray

from ..bag.cdr import decode_float64_multi_array, decode_joint_state_named
from ..errors import CdrError, ConfigError
from ..live_view import DEFAULT_DISPLAY_RATE, FoxgloveView, LiveView
from .executor import run_node
from .lifecycle import EXIT_OK, end_when_plant_leaves
from .params import declare_int_parameter, declare_node_run, refuse_run_changes
from .topics import OBSERVER_QOS, STEADY_CLOCK, TOPIC_EFFORT, TOPIC_JOINT_STATES

MAX_DISPLAY_RATE = 240.0


class ViewerNode:
    """Thin wrapper around :class:`LiveView` and :class:`FoxgloveView`."""

    def __init__(self) -> None:
        self.node = Node("viewer")
        node = self.node
        run = declare_node_run(node)
        port = declare_int_parameter(node, "port", 8765, "WebSocket port of the Foxglove server (0: any free)",
                                     lo=0, hi=65535)
        host = str(node.declare_parameter("host", "127.0.0.1").value)
        rate = node.declare_parameter("display_rate", DEFAULT_DISPLAY_RATE).value
        if isinstance(rate, bool) or not isinstance(rate, (int, float)) or not 0.0 < rate <= MAX_DISPLAY_RATE:
            raise ConfigError(f"parameter display_rate: frames per second of wall time in (0, {MAX_DISPLAY_RATE:g}], "
                              f"got {rate!r}")
        node.add_on_set_parameters_callback(refuse_run_changes)
        self.spec = run.spec
        self.view = LiveView(self.spec)
        try:
            self.server = FoxgloveView(self.view, host=host, port=port)
        except (OSError, RuntimeError) as exc:
            raise ConfigError(f"parameter port: cannot serve on {host}:{port} ({exc})") from None
        self.done = False
        self.exit_code = EXIT_OK
        self.states_received = 0
        node.create_subscription(JointState, TOPIC_JOINT_STATES, self.on_state, OBSERVER_QOS, raw=True)
        node.create_subscription(Float64MultiArray, TOPIC_EFFORT, self.on_effort, OBSERVER_QOS, raw=True)
        node.create_timer(1.0 / float(rate), self.show, clock=STEADY_CLOCK)
        self.plant_watch = end_when_plant_leaves(self, lambda: self.states_received)
        node.get_logger().info(f"serving the {self.spec.robot} run on ws://{host}:{self.server.port} "
                               f"at {float(rate):g} frames/s (Foxglove: Open connection)")

    def on_state(self, data: bytes) -> None:
        try:
            names, sec, nanosec, position, _, _ = decode_joint_state_named(data)
        except CdrError:
            return  # an observer: a malformed message is the plant's and the recorder's concern
        self.states_received += 1
        self.view.add_state(sec, nanosec, names, position)

    def on_effort(self, data: bytes) -> None:
        try:
            _, values = decode_float64_multi_array(data)
        except CdrError:
            return
        self.view.add_effort(values)

    def show(self) -> None:
        frame = self.view.frame()
        if frame is not None:
            self.server.publish(frame, time.time_ns())
        self.plant_watch.poll()

    def close(self) -> None:
        self.server.close()


def main(args: Sequence[str] | None = None) -> int:
    return run_node("viewer", ViewerNode, args)


if __name__ == "__main__":
    sys.exit(main())
