"""A controller's ``~/controller_state``, its action goals' feedback and its saturation
diagnostic, at :data:`FEEDBACK_HZ` (joint_trajectory_controller's action monitor rate).

Real time: :meth:`StatePublisher.publish` is called by the control loop in its spare time
(``idle``), never from a thread of its own, whose message conversions would hold the GIL while
a tick is due; a loop with no spare time (a busy machine) still calls it after a tick every
:data:`~pdsmc_ros.nodes.serve_loop.IDLE_STARVED_S`, so a goal's client is never left without
feedback; lockstep (no deadlines): by a timer of the action server's thread
(:mod:`.follow_joint_trajectory`).
"""

from __future__ import annotations

import time
from collections.abc import Iterable
from typing import TYPE_CHECKING, Any

import numpy as np
from builtin_interfaces.msg import Time
from control_msgs.action import FollowJointTrajectory
from control_msgs.msg import JointTrajectoryControllerState
from rclpy.node import Node
from std_msgs.msg import Header
from trajectory_msgs.msg import JointTrajectoryPoint

from ..runtime.goal import GoalExecution
from ..runtime.joint_map import JointMap
from .diagnostics import Diagnostics

if TYPE_CHECKING:
    from .controller import ControllerNode

FEEDBACK_HZ = 20.0  # feedback and ~/controller_state (joint_trajectory_controller's action monitor rate)
SATURATION_EVERY_S = 1.0  # a diagnostic when the clamp count has grown, at most this often


def _header(t: float) -> Header:
    sec = int(np.floor(t))
    return Header(stamp=Time(sec=sec, nanosec=min(int((t - sec) * 1e9), 999_999_999)))


def _point(joint_map: JointMap, q: Any, qd: Any, qdd: Any = None) -> JointTrajectoryPoint:
    """A point in ``joints`` order from robot-order vectors."""
    to_user = joint_map.to_user
    point = JointTrajectoryPoint(positions=to_user(np.asarray(q, dtype=float)).tolist(),
                                 velocities=to_user(np.asarray(qd, dtype=float)).tolist())
    if qdd is not None:
        point.accelerations = to_user(np.asarray(qdd, dtype=float)).tolist()
    return point


class StatePublisher:
    """``controller``'s state topic on ``node`` (the action server's), and its saturation diagnostic."""

    def __init__(self, node: Node, controller: ControllerNode) -> None:
        self.controller = controller
        base = controller.node.get_fully_qualified_name()
        self.state_pub = node.create_publisher(JointTrajectoryControllerState, f"{base}/controller_state", 10)
        self.saturation = Diagnostics(controller.node, "controller: torque limits", controller.core.spec.robot,
                                      values=lambda: {"saturated_periods": str(controller.guard.clamped)})
        self.saturated_seen, self.ticks, self.next_publish = 0, 0, 0.0

    def publish(self, until: float, goals: Iterable[tuple[Any, GoalExecution]]) -> None:
        """At :data:`FEEDBACK_HZ`: ``~/controller_state`` from the loop's latest period, the
        feedback of each active goal (``(handle, execution)``) and (once a second, if the clamp
        count grew) a saturation diagnostic; it stops once ``time.perf_counter()`` reaches ``until``."""
        now = time.perf_counter()
        if now < self.next_publish:
            return
        self.next_publish = max(self.next_publish + 1.0 / FEEDBACK_HZ, now)
        ctl = self.controller
        joints, joint_map = list(ctl.params.joints), ctl.joint_map
        snapshot = ctl.core.snapshot
        if snapshot is not None:
            t, q, qd, ref, tau = snapshot
            q, qd = np.asarray(q, dtype=float), np.asarray(qd, dtype=float)
            msg = JointTrajectoryControllerState(header=_header(t), joint_names=joints,
                                                 reference=_point(joint_map, *ref), feedback=_point(joint_map, q, qd),
                                                 error=_point(joint_map, ref[0] - q, ref[1] - qd))
            msg.output.effort = joint_map.to_user(np.asarray(tau, dtype=float)).tolist()
            self.state_pub.publish(msg)
        for handle, execution in goals:
            feedback = execution.feedback
            if feedback is None or time.perf_counter() >= until:
                continue
            handle.publish_feedback(FollowJointTrajectory.Feedback(
                header=_header(feedback.time), joint_names=joints, desired=_point(joint_map, *feedback.desired),
                actual=_point(joint_map, *feedback.actual), error=_point(joint_map, *feedback.error)))
        self.ticks += 1
        if self.ticks % int(FEEDBACK_HZ * SATURATION_EVERY_S) == 0 and ctl.guard.clamped > self.saturated_seen \
                and time.perf_counter() < until:
            self.saturated_seen = ctl.guard.clamped
            self.saturation.publish("warn", f"torque clamped to the limits in {ctl.guard.clamped} periods so far")
