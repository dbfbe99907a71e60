"""The controller's FollowJointTrajectory action server and ``~/controller_state``, off the loop.

``control_msgs/action/FollowJointTrajectory`` on ``/<controller>/follow_joint_trajectory``
with joint_trajectory_controller's semantics (:mod:`pdsmc_ros.runtime.goal`). The server
lives on a node of its own (``<controller>_action``, no parameter services or rosout) spun
by a thread of its own with a small multi-threaded executor: a controller with its action
server in the control loop's executor answered 142 of 2,000 states at 1 kHz; with the
server's waiting in another thread it answered every one. The control loop checks the
active goal every period; this thread only validates goals and waits for their outcome. The
feedback and the controller state (:meth:`FollowJointTrajectoryServer.publish`, :data:`FEEDBACK_HZ`)
go out in the control loop's spare time in real time (``idle``), by a timer of this thread in lockstep.
"""

from __future__ import annotations

import threading
import time
from typing import TYPE_CHECKING, Any

import numpy as np
from builtin_interfaces.msg import Time
from control_msgs.action import FollowJointTrajectory
from control_msgs.msg import JointTrajectoryControllerState
from rclpy.action import ActionServer, CancelResponse, GoalResponse
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.executors import MultiThreadedExecutor
from rclpy.node import Node
from trajectory_msgs.msg import JointTrajectoryPoint

from ..runtime.goal import INVALID_GOAL, GoalExecution, Outcome, resolve_tolerances, validate_goal
from ..runtime.joint_trajectory import JointTrajectoryReference
from .diagnostics import Diagnostics
from .inputs import Times

if TYPE_CHECKING:
    from .controller import ControllerNode

FEEDBACK_HZ = 20.0  # feedback and ~/controller_state (joint_trajectory_controller's action monitor rate)
SOURCE_SKEW_S = 5.0  # a zero-stamped trajectory starts at its source time if that is at most this old
CANCEL_STATE_WAIT_S = 1.0  # longest wait for rclpy to mark a canceled goal's handle canceling
SATURATION_EVERY_S = 1.0  # a diagnostic when the clamp count has grown, at most this often


def _stamp(t: float) -> Time:
    sec = int(np.floor(t))
    return Time(sec=sec, nanosec=min(int((t - sec) * 1e9), 999_999_999))


def _point(controller: ControllerNode, q: Any, qd: Any, qdd: Any = None) -> JointTrajectoryPoint:
    """A point in ``joints`` order from robot-order vectors."""
    to_user = controller.joint_map.to_user
    point = JointTrajectoryPoint(positions=to_user(np.asarray(q, dtype=float)).tolist(),
                                 velocities=to_user(np.asarray(qd, dtype=float)).tolist())
    if qdd is not None:
        point.accelerations = to_user(np.asarray(qdd, dtype=float)).tolist()
    return point


def topic_trajectory(controller: ControllerNode, data: bytes, times: Times) -> bool:
    """A ``~/joint_trajectory`` message: refused (logged) or driving from now on (whether it drives).

    Real time: a zero ``header.stamp`` starts when the message was sent (``times``: the
    middleware's source and reception times; the reception time if the source time is
    implausible, e.g. another machine's clock off by more than :data:`SOURCE_SKEW_S`), so no
    wait -- the controller still starting, DDS repairing a sample its reader dropped before it
    knew the writer -- shifts the trajectory."""
    log = controller.node.get_logger()
    topic = controller.node.resolve_topic_name("~/joint_trajectory")
    now = controller.now()
    if not controller.lockstep:
        sent, received = times
        if sent is not None and now - SOURCE_SKEW_S <= sent <= now:
            now = sent
        elif received is not None and received <= now:
            now = received
    state = controller.last_state[1:] if controller.last_state is not None else None
    reference, problem = JointTrajectoryReference.from_serialized(controller.selector, data, now, state)
    if reference is not None and controller.limits is not None:
        problem = controller.limits.trajectory_problem(reference)
    if reference is None or problem:
        log.error(f"{topic}: trajectory refused: {problem}")
        return False
    if controller.goals.replace(reference, f"Current goal preempted by a trajectory on {topic}.") is not None:
        log.warn(f"{topic}: the active action goal was preempted by this trajectory")
    log.info(f"{topic}: {len(reference.times)} points until t = {reference.end_time:.3f} s; driving from it")
    return True


class FollowJointTrajectoryServer:
    """The action server of ``controller`` and its state publisher, in a thread of their own."""

    def __init__(self, controller: ControllerNode) -> None:
        self.controller = controller
        base = controller.node.get_fully_qualified_name()
        self.node = Node(f"{controller.node.get_name()}_action", namespace=controller.node.get_namespace(),
                         context=controller.node.context, use_global_arguments=False,
                         start_parameter_services=False, enable_rosout=False)
        group = ReentrantCallbackGroup()
        self.server = ActionServer(self.node, FollowJointTrajectory, f"{base}/follow_joint_trajectory",
                                   execute_callback=self.execute, goal_callback=self.on_goal,
                                   cancel_callback=self.on_cancel, callback_group=group)
        self.state_pub = self.node.create_publisher(JointTrajectoryControllerState, f"{base}/controller_state", 10)
        self.saturation = Diagnostics(controller.node, "controller: torque limits", controller.spec.robot,
                                      values=lambda: {"saturated_periods": str(controller.guard.clamped)})
        self.saturated_seen, self.ticks, self.next_publish = 0, 0, 0.0
        self.goals: dict[bytes, tuple[Any, GoalExecution]] = {}  # active goals: (handle, execution)
        if controller.lockstep:  # no deadlines: a timer here; real time: the loop's spare time (idle)
            self.node.create_timer(1.0 / FEEDBACK_HZ, lambda: self.publish(float("inf")), callback_group=group)
        self.executor = MultiThreadedExecutor(num_threads=3, context=controller.node.context)
        self.executor.add_node(self.node)
        self.stopping = threading.Event()
        self.thread = threading.Thread(target=self._spin, name="follow_joint_trajectory", daemon=True)
        self.thread.start()

    def _spin(self) -> None:
        while not self.stopping.is_set() and self.controller.node.context.ok():
            self.executor.spin_once(timeout_sec=0.1)

    def stop(self) -> None:
        """End the thread and the node (the process is stopping)."""
        self.stopping.set()
        for _, execution in list(self.goals.values()):
            execution.done.set()  # their execute callbacks return
        self.thread.join(timeout=2.0)
        self.executor.shutdown(timeout_sec=1.0)
        self.server.destroy()
        self.node.destroy_node()

    # -- goals ---------------------------------------------------------------- #
    def on_goal(self, request: Any) -> GoalResponse:  # noqa: ARG002
        if not self.controller.active:  # joint_trajectory_controller: only a running controller accepts
            self.node.get_logger().error("goal rejected: the controller is not active")
            return GoalResponse.REJECT
        return GoalResponse.ACCEPT  # validated in execute: its result says why it is refused

    def on_cancel(self, goal_handle: Any) -> CancelResponse:
        found = self.goals.get(bytes(goal_handle.goal_id.uuid))
        if found is not None and self.controller.goals.cancel(found[1]):
            self.controller.node.get_logger().info("action goal canceled: holding")
        return CancelResponse.ACCEPT

    def start(self, goal: Any) -> tuple[GoalExecution | None, FollowJointTrajectory.Result | None]:
        """Validate ``goal`` and drive it; ``(execution, None)`` or ``(None, the refusal's result)``."""
        ctl = self.controller
        trajectory = goal.trajectory
        stamp = trajectory.header.stamp.sec + trajectory.header.stamp.nanosec * 1e-9
        points = [(p.positions, p.velocities, p.accelerations, p.time_from_start.sec, p.time_from_start.nanosec)
                  for p in trajectory.points]
        state = ctl.last_state[1:] if ctl.last_state is not None else None
        reference, refusal = validate_goal(ctl.selector, stamp, trajectory.joint_names, points, ctl.now(),
                                           state, ctl.limits)  # type: ignore[arg-type]
        if reference is None or refusal is not None:
            refusal = refusal or Outcome("aborted", INVALID_GOAL, "refused")
            ctl.node.get_logger().error(f"action goal refused ({refusal.error_code}): {refusal.error_string}")
            return None, FollowJointTrajectory.Result(error_code=refusal.error_code,
                                                       error_string=refusal.error_string)
        goal_time = goal.goal_time_tolerance.sec + goal.goal_time_tolerance.nanosec * 1e-9
        tolerances, warning = resolve_tolerances(
            ctl.params.tolerances, ctl.selector.joints,
            [(t.name, t.position, t.velocity) for t in goal.path_tolerance],
            [(t.name, t.position, t.velocity) for t in goal.goal_tolerance], goal_time)
        if warning:
            ctl.node.get_logger().warn(warning)
        execution = GoalExecution(reference, tolerances, ctl.selector.joints)
        if ctl.goals.start(execution) is not None:
            ctl.node.get_logger().info("the active action goal was preempted by a new one")
        ctl.node.get_logger().info(f"action goal accepted: {len(reference.times)} points until "
                                   f"t = {reference.end_time:.3f} s")
        return execution, None

    def execute(self, goal_handle: Any) -> FollowJointTrajectory.Result:
        execution, refusal = self.start(goal_handle.request)
        if execution is None:
            goal_handle.abort()
            return refusal
        key = bytes(goal_handle.goal_id.uuid)
        self.goals[key] = (goal_handle, execution)  # its feedback: publish()
        try:
            while not execution.done.wait(0.1) and not self.stopping.is_set():
                pass
        finally:
            del self.goals[key]
        outcome = execution.outcome
        if outcome is None:  # stopping
            goal_handle.abort()
            return FollowJointTrajectory.Result(error_code=INVALID_GOAL, error_string="the controller is stopping")
        if outcome.status == "canceled":
            # the cancel callback ended the goal; rclpy marks the handle canceling just after it returns
            deadline = time.monotonic() + CANCEL_STATE_WAIT_S
            while not goal_handle.is_cancel_requested and time.monotonic() < deadline:
                time.sleep(0.001)
        if outcome.status == "succeeded":
            goal_handle.succeed()
        elif outcome.status == "canceled" and goal_handle.is_cancel_requested:
            goal_handle.canceled()
        else:
            goal_handle.abort()
        return FollowJointTrajectory.Result(error_code=outcome.error_code, error_string=outcome.error_string)

    # -- state ---------------------------------------------------------------- #
    def _header(self, t: float) -> Any:
        from std_msgs.msg import Header

        return Header(stamp=_stamp(t))

    def publish(self, until: float) -> None:
        """At :data:`FEEDBACK_HZ`: ``~/controller_state`` from the loop's latest period, each active
        goal's feedback and (once a second, if the clamp count grew) a saturation diagnostic.

        Real time: called by the control loop in its spare time (``idle``), never from a thread
        of its own, whose message conversions would hold the GIL while a tick is due; it stops
        once ``time.perf_counter()`` reaches ``until``."""
        now = time.perf_counter()
        if now < self.next_publish:
            return
        self.next_publish = max(self.next_publish + 1.0 / FEEDBACK_HZ, now)
        ctl = self.controller
        snapshot = ctl.snapshot
        if snapshot is not None:
            t, q, qd, ref, tau = snapshot
            q, qd = np.asarray(q, dtype=float), np.asarray(qd, dtype=float)
            msg = JointTrajectoryControllerState(header=self._header(t), joint_names=list(ctl.params.joints),
                                                 reference=_point(ctl, *ref), feedback=_point(ctl, q, qd),
                                                 error=_point(ctl, ref[0] - q, ref[1] - qd))
            msg.output.effort = ctl.joint_map.to_user(np.asarray(tau, dtype=float)).tolist()
            self.state_pub.publish(msg)
        for handle, execution in list(self.goals.values()):
            feedback = execution.feedback
            if feedback is None or time.perf_counter() >= until:
                continue
            handle.publish_feedback(FollowJointTrajectory.Feedback(
                header=self._header(feedback.time), joint_names=list(ctl.params.joints),
                desired=_point(ctl, *feedback.desired), actual=_point(ctl, *feedback.actual),
                error=_point(ctl, *feedback.error)))
        self.ticks += 1
        if self.ticks % int(FEEDBACK_HZ * SATURATION_EVERY_S) == 0 and ctl.guard.clamped > self.saturated_seen \
                and time.perf_counter() < until:
            self.saturated_seen = ctl.guard.clamped
            self.saturation.publish("warn", f"torque clamped to the limits in {ctl.guard.clamped} periods so far")
