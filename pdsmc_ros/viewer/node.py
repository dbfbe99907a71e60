"""Viewer node: the run live in Foxglove (``ws://localhost:8765``, "Open connection").

Wiring around :class:`~pdsmc_ros.viewer.live_view.LiveView` and its Foxglove server: the node
takes the plant's states throttled to 100 per second of sim time (``/joint_states_throttle``,
best effort: the loop's own topics get no extra reader) and, at ``display_rate`` frames per
second of wall time, streams the newest state -- the arm's link transforms, its URDF, the
desired path (the run's references, computed as the trajectory node does) and the actual
one, the joint errors, contour error and torques (``live_view.CHANNELS``). Lockstep or real
time alike. It ends when the plant leaves the graph, or on Ctrl-C.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Sequence

from rclpy.node import Node
from sensor_msgs.msg import JointState

from ..bag.cdr import decode_joint_state_named
from ..errors import CdrError, ConfigError
from ..loop.lifecycle import EXIT_OK, end_when_plant_leaves
from ..loop.process import run_node
from ..parameters import VIEWER
from ..parameters.ros import declare
from ..ros.node_run import declare_node_run
from ..ros.topics import OBSERVER_QOS, STEADY_CLOCK, TOPIC_JOINT_STATES_THROTTLED
from .live_view import FoxgloveView, LiveView


class ViewerNode:
    """Thin wrapper around :class:`LiveView` and :class:`FoxgloveView`."""

    def __init__(self) -> None:
        self.node = Node("viewer")
        node = self.node
        run = declare_node_run(node)
        own = declare(node, VIEWER)  # read-only, as the run's (declare_node_run guards them)
        port, host, rate = own["port"], own["host"], own["display_rate"]
        self.spec = run.spec
        self.view = LiveView(self.spec)
        try:
            self.server = FoxgloveView(self.view, host=host, port=port)
        except (OSError, RuntimeError) as exc:
            raise ConfigError(f"parameter port: cannot serve on {host}:{port} ({exc})") from None
        self.done = False
        self.exit_code = EXIT_OK
        self.states_received = 0
        self.newest_state: bytes | None = None
        # the plant's states throttled to 100 per second of sim time (their effort field is the
        # applied torque): the loop's own /joint_states gets no extra reader
        node.create_subscription(JointState, TOPIC_JOINT_STATES_THROTTLED, self.on_state, OBSERVER_QOS, raw=True)
        node.create_timer(1.0 / float(rate), self.show, clock=STEADY_CLOCK)
        self.plant_watch = end_when_plant_leaves(self, lambda: self.states_received)
        node.get_logger().info(f"serving the {self.spec.robot} run on ws://{host}:{self.server.port} "
                               f"at {float(rate):g} frames/s (Foxglove: Open connection)")

    def on_state(self, data: bytes) -> None:
        # keep the bytes only; the newest is decoded when a frame is shown
        self.newest_state = data
        self.states_received += 1

    def show(self) -> None:
        state, self.newest_state = self.newest_state, None
        try:
            if state is not None:
                names, sec, nanosec, position, _, effort = decode_joint_state_named(state)
                self.view.add_state(sec, nanosec, names, position)
                self.view.add_effort(effort)
        except CdrError:
            pass  # an observer: a malformed message is the plant's and the recorder's concern
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
