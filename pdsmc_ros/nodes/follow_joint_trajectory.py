"""The controller's FollowJointTrajectory action server and ``~/joint_trajectory``, off the loop.

``control_msgs/action/FollowJointTrajectory`` on ``/<controller>/follow_joint_trajectory``
with joint_trajectory_controller's semantics (:mod:`pdsmc_ros.runtime.goal`; the decisions:
:class:`~pdsmc_ros.runtime.controller.ControllerCore`). The server
lives on a node of its own (``<controller>_action``, no parameter services or rosout) spun
by a thread of its own with a small multi-threaded executor: a controller with its action
server in the control loop's executor answered 142 of 2,000 states at 1 kHz; with the
server's waiting in another thread it answered every one. The control loop checks the
active goal every period; this thread only validates goals and waits for their outcome. The
feedback and the controller state (:mod:`.controller_state`) go out in the control loop's
spare time in real time (``idle``), by a timer of this thread in lockstep.
"""

from __future__ import annotations

import time
from typing import TYPE_CHECKING, Any

from control_msgs.action import FollowJointTrajectory
from rclpy.action import ActionServer, CancelResponse, GoalResponse
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.executors import MultiThreadedExecutor
from rclpy.node import Node

from ..runtime.goal import INVALID_GOAL, GoalExecution, Outcome
from .controller_state import FEEDBACK_HZ, StatePublisher
from .executor_thread import ExecutorThread
from .inputs import Times

if TYPE_CHECKING:
    from .controller import ControllerNode

CANCEL_STATE_WAIT_S = 1.0  # longest wait for rclpy to mark a canceled goal's handle canceling


def _seconds(duration: Any) -> float:
    """A ``builtin_interfaces`` Time or Duration in seconds."""
    return duration.sec + duration.nanosec * 1e-9


def topic_trajectory(controller: ControllerNode, data: bytes, times: Times) -> bool:
    """A ``~/joint_trajectory`` message: refused (logged) or driving from now on (whether it
    drives; where it starts: :meth:`~pdsmc_ros.runtime.controller.ControllerCore.topic_trajectory`)."""
    log = controller.node.get_logger()
    topic = controller.node.resolve_topic_name("~/joint_trajectory")
    reference, problem, preempted = controller.core.topic_trajectory(
        data, times, controller.now(), f"Current goal preempted by a trajectory on {topic}.")
    if reference is None:
        log.error(f"{topic}: trajectory refused: {problem}")
        return False
    if preempted:
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
        self.state = StatePublisher(self.node, controller)
        self.goals: dict[bytes, tuple[Any, GoalExecution]] = {}  # active goals: (handle, execution)
        if controller.lockstep:  # no deadlines: a timer here; real time: the loop's spare time (idle)
            self.node.create_timer(1.0 / FEEDBACK_HZ, lambda: self.publish(float("inf")), callback_group=group)
        self.executor = MultiThreadedExecutor(num_threads=3, context=controller.node.context)
        self.executor.add_node(self.node)
        # asleep until there is work (it woke every 0.1 s at first: ~0.2 ms under the GIL, a late
        # control period of a composed process ten times a second)
        self.spinner = ExecutorThread(self.executor, self.node, name="follow_joint_trajectory")

    def stop(self) -> None:
        """End the thread and the node (the process is stopping)."""
        for _, execution in list(self.goals.values()):
            execution.done.set()  # their execute callbacks return
        self.spinner.stop()
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
        if found is not None and self.controller.core.goals.cancel(found[1]):
            self.controller.node.get_logger().info("action goal canceled: holding")
        return CancelResponse.ACCEPT

    def start(self, goal: Any) -> tuple[GoalExecution | None, FollowJointTrajectory.Result | None]:
        """Validate ``goal`` and drive it; ``(execution, None)`` or ``(None, the refusal's result)``."""
        ctl, log = self.controller, self.controller.node.get_logger()
        trajectory = goal.trajectory
        points = [(p.positions, p.velocities, p.accelerations, p.time_from_start.sec, p.time_from_start.nanosec)
                  for p in trajectory.points]
        execution, warning, preempted = ctl.core.start_goal(
            _seconds(trajectory.header.stamp), trajectory.joint_names, points, ctl.now(),
            [(t.name, t.position, t.velocity) for t in goal.path_tolerance],
            [(t.name, t.position, t.velocity) for t in goal.goal_tolerance],
            _seconds(goal.goal_time_tolerance), ctl.params.tolerances)
        if isinstance(execution, Outcome):
            log.error(f"action goal refused ({execution.error_code}): {execution.error_string}")
            return None, FollowJointTrajectory.Result(error_code=execution.error_code,
                                                       error_string=execution.error_string)
        if warning:
            log.warn(warning)
        if preempted:
            log.info("the active action goal was preempted by a new one")
        log.info(f"action goal accepted: {len(execution.reference.times)} points until "
                 f"t = {execution.reference.end_time:.3f} s")
        return execution, None

    def execute(self, goal_handle: Any) -> FollowJointTrajectory.Result:
        execution, refusal = self.start(goal_handle.request)
        if execution is None:
            goal_handle.abort()
            return refusal
        key = bytes(goal_handle.goal_id.uuid)
        self.goals[key] = (goal_handle, execution)  # its feedback: publish()
        try:
            while not execution.done.wait(0.1) and not self.spinner.stopping.is_set():
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

    def publish(self, until: float) -> None:
        """The controller state and the active goals' feedback (:meth:`StatePublisher.publish`)."""
        self.state.publish(until, list(self.goals.values()))
