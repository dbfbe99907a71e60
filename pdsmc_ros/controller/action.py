"""The controller's FollowJointTrajectory action server, ``~/joint_trajectory``, ``~/query_state``
and ``~/controller_state``, off the loop.

``control_msgs/action/FollowJointTrajectory`` on ``/<controller>/follow_joint_trajectory``
with joint_trajectory_controller's semantics (:mod:`pdsmc_ros.controller.goals`; the decisions:
:class:`~pdsmc_ros.controller.core.ControllerCore`). As JTC, a goal is validated when it
arrives (``goal_callback``) and an invalid one is rejected -- the client's ``accepted`` is
False, no result -- with the reason in one log line and on ``/diagnostics``; an accepted goal
preempts the active one (``handle_accepted_callback``) and is then watched until it ends
(``execute_callback``). ``~/joint_trajectory`` messages go through the same checks; a refused
one is logged and dropped, the running motion untouched. ``~/query_state``
(``control_msgs/srv/QueryTrajectoryState``) answers the reference at a given time of the
running trajectory. Accepted goals are published as the ``send_goal`` service's events
(``<action>/_action/send_goal/_service_event``, ``action_introspection``) -- the topic ROS 2's
service introspection uses, which Jazzy's rcl_action does not offer for actions -- so a recorder
that did not send them still has each goal's trajectory.

The server lives on a node of its own (``<controller>_action``, no parameter services or
rosout) spun by a thread of its own with a small multi-threaded executor: a controller with
its action server in the control loop's executor answered 142 of 2,000 states at 1 kHz; with
the server's waiting in another thread it answered every one. Real time: that node, its thread
and the validation run in a process of their own (:mod:`.sidecar.goal_process`), which hands the loop's
process the goals and trajectories it accepted; lockstep (no deadlines): in the controller's
process, where ``~/joint_trajectory`` is taken by the loop, which computes the waiting step at
once. Validation never runs in the loop's thread: the loop only checks the active goal every
period. A trajectory longer than :data:`~pdsmc_ros.controller.joint_trajectory.MAX_POINTS` is
refused before it is looked at.

:class:`StatePublisher` sends ``~/controller_state``, the action goals' feedback and the
saturation diagnostic at :data:`FEEDBACK_HZ` (joint_trajectory_controller's action monitor
rate): real time, when the loop's process sends its latest period (in the loop's spare time, at
that rate; a loop with no spare time still does after a tick every
:data:`~pdsmc_ros.loop.serve.IDLE_STARVED_S`, so a goal's client is never left without
feedback); lockstep, by a timer of the action server's thread. Without a goal process (an arm a
child cannot rebuild), the loop calls :meth:`StatePublisher.publish` in its spare time.

Both read the controller through :class:`ControllerView` (what they use of the controller),
never the node's module: the node imports this one, not the other way round.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable, Sequence
from typing import Any, Protocol

import numpy as np
from builtin_interfaces.msg import Time
from control_msgs.action import FollowJointTrajectory
from control_msgs.msg import JointTrajectoryControllerState
from control_msgs.srv import QueryTrajectoryState
from rclpy.action import ActionServer, CancelResponse, GoalResponse
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.context import Context
from rclpy.executors import MultiThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.serialization import serialize_message
from service_msgs.msg import ServiceEventInfo
from std_msgs.msg import Header
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from ..loop.executor_thread import ExecutorThread
from ..loop.inputs import Times
from ..parameters.joint_map import JointMap
from ..ros import topics
from ..ros.diagnostics import Diagnostics
from .core import GoalStart, Tolerance
from .goals import INVALID_GOAL, GoalExecution, Outcome
from .joint_trajectory import JointTrajectoryReference, RawPoint


class ControllerView(Protocol):
    """What the action server and the state publisher read and call of the controller: the
    controller node itself in its process (:class:`~pdsmc_ros.controller.node.LocalView`), or its
    stand-in in the goal process (:class:`~pdsmc_ros.controller.sidecar.remote_view.RemoteView`)."""

    name: str  # the controller node's name, namespace and fully qualified name
    namespace: str
    base: str
    context: Context
    logger: Any  # the controller's logger (its lines carry the controller's name)
    robot: str  # the diagnostics' hardware id
    joints: Sequence[str]  # the controlled joints in the user's order
    joint_map: JointMap
    action_introspection: str
    lockstep: bool
    active: bool  # commanding: only an active controller takes goals and trajectories

    def now(self) -> float:
        """The controller's time (s)."""

    def resolve(self, topic: str) -> str:
        """``topic`` resolved as the controller node resolves it."""

    def check_goal(self, stamp: float, names: Sequence[str], points: Sequence[RawPoint], effort_sizes: Sequence[int],
                   now: float, path: Sequence[Tolerance], goal: Sequence[Tolerance], goal_time: float) -> GoalStart:
        """An action goal validated (:func:`~.core.check_goal`)."""

    def check_topic_trajectory(self, stamp: float, names: Sequence[str], points: Sequence[RawPoint],
                               effort_sizes: Sequence[int], times: Times, now: float
                               ) -> tuple[JointTrajectoryReference | None, str]:
        """A ``~/joint_trajectory`` validated (:func:`~.core.check_topic_trajectory`)."""

    def start_goal(self, key: bytes, execution: GoalExecution) -> bool:
        """Drive an accepted goal from now on; whether it preempts another action goal."""

    def cancel_goal(self, key: bytes, execution: GoalExecution) -> bool:
        """Cancel ``execution`` if it is the active goal (it ends CANCELED; the arm holds); whether it was."""

    def follow(self, reference: JointTrajectoryReference) -> bool:
        """A validated topic trajectory drives from now on; whether an action goal goes on against it."""

    def driving(self) -> JointTrajectoryReference | None:
        """The trajectory driving the controller now (None: a hold, the reference stream, nothing)."""

    def latest(self) -> tuple[tuple[Any, ...] | None, int]:
        """The latest control period's ``(t, q, qd, reference, torque)`` (robot order; None before
        the first) and the number of periods the torque was clamped so far."""


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
    """``controller``'s state topic on ``node`` (the action server's), and its saturation diagnostic.

    ``sink``: the state messages serialized, handed to it instead of published here (the goal
    process: the controller's process publishes them, from the participant a recorder already knows).
    """

    def __init__(self, node: Node, controller: ControllerView, *, sink: Callable[[bytes], None] | None = None) -> None:
        self.controller = controller
        self.sink = sink
        self.state_pub = None if sink is not None else node.create_publisher(
            JointTrajectoryControllerState, controller_state_topic(controller.base), 10)
        self.saturation = Diagnostics(node, "controller: torque limits", controller.robot, logger=controller.logger,
                                      values=lambda: {"saturated_periods": str(self.saturated)})
        self.saturated = self.saturated_seen = self.ticks = 0
        self.next_publish = 0.0

    def publish(self, until: float, goals: Iterable[tuple[Any, GoalExecution]]) -> None:
        """At :data:`FEEDBACK_HZ` (:meth:`send`); it stops once ``time.perf_counter()`` reaches ``until``."""
        now = time.perf_counter()
        if now < self.next_publish:
            return
        self.next_publish = max(self.next_publish + 1.0 / FEEDBACK_HZ, now)
        self.send(until, goals)

    def send(self, until: float, goals: Iterable[tuple[Any, GoalExecution]]) -> None:
        """``~/controller_state`` from the loop's latest period, the feedback of each active goal
        (``(handle, execution)``) and (once a second, if the clamp count grew) a saturation
        diagnostic; it stops once ``time.perf_counter()`` reaches ``until``."""
        ctl = self.controller
        joints, joint_map = list(ctl.joints), ctl.joint_map
        snapshot, self.saturated = ctl.latest()
        if snapshot is not None:
            t, q, qd, ref, tau = snapshot
            q, qd = np.asarray(q, dtype=float), np.asarray(qd, dtype=float)
            msg = JointTrajectoryControllerState(header=_header(t), joint_names=joints,
                                                 reference=_point(joint_map, *ref), feedback=_point(joint_map, q, qd),
                                                 error=_point(joint_map, ref[0] - q, ref[1] - qd))
            msg.output.effort = joint_map.to_user(np.asarray(tau, dtype=float)).tolist()
            if self.sink is not None:
                self.sink(serialize_message(msg))
            elif self.state_pub is not None:
                self.state_pub.publish(msg)
        for handle, execution in goals:
            feedback = execution.feedback
            if feedback is None or time.perf_counter() >= until:
                continue
            handle.publish_feedback(FollowJointTrajectory.Feedback(
                header=_header(feedback.time), joint_names=joints, desired=_point(joint_map, *feedback.desired),
                actual=_point(joint_map, *feedback.actual), error=_point(joint_map, *feedback.error)))
        self.ticks += 1
        if self.ticks % int(FEEDBACK_HZ * SATURATION_EVERY_S) == 0 and self.saturated > self.saturated_seen \
                and time.perf_counter() < until:
            self.saturated_seen = self.saturated
            self.saturation.publish("warn", f"torque clamped to the limits in {self.saturated} periods so far")


CANCEL_STATE_WAIT_S = 1.0  # longest wait for rclpy to mark a canceled goal's handle canceling
PENDING_KEPT = 64  # validated goals waiting for their acceptance (more: clients that vanished)


def _seconds(duration: Any) -> float:
    """A ``builtin_interfaces`` Time or Duration in seconds."""
    return duration.sec + duration.nanosec * 1e-9


class _Points(Sequence):  # type: ignore[type-arg]
    """A message's points as :data:`RawPoint` tuples, converted when read (its size is checked first)."""

    def __init__(self, points: Sequence[Any]) -> None:
        self.points = points

    def __len__(self) -> int:
        return len(self.points)

    def __getitem__(self, k: Any) -> Any:
        p = self.points[k]
        return (p.positions, p.velocities, p.accelerations, p.time_from_start.sec, p.time_from_start.nanosec)


class _EffortSizes(Sequence):  # type: ignore[type-arg]
    def __init__(self, points: Sequence[Any]) -> None:
        self.points = points

    def __len__(self) -> int:
        return len(self.points)

    def __getitem__(self, k: Any) -> Any:
        return len(self.points[k].effort)


def trajectory_fields(msg: JointTrajectory) -> tuple[float, tuple[str, ...], Sequence[RawPoint], Sequence[int]]:
    """A ``JointTrajectory``'s stamp (s), joint names, points and effort sizes, as the core takes them."""
    return _seconds(msg.header.stamp), tuple(msg.joint_names), _Points(msg.points), _EffortSizes(msg.points)


def topic_trajectory(controller: ControllerView, msg: JointTrajectory, times: Times, report: Diagnostics) -> bool:
    """A ``~/joint_trajectory`` message: refused (one log line and ``/diagnostics`` by ``report``)
    or driving from now on (whether it drives; where it starts:
    :func:`~pdsmc_ros.controller.core.check_topic_trajectory`)."""
    topic = controller.resolve(topics.TOPIC_JOINT_TRAJECTORY)
    if not controller.active:
        report.report("warn", f"{topic}: trajectory refused: the controller is not active")
        return False
    reference, problem = controller.check_topic_trajectory(*trajectory_fields(msg), times, controller.now())
    if reference is None:
        report.report("error", f"{topic}: trajectory refused: {problem}")
        return False
    goes_on = "; the active action goal goes on against it" if controller.follow(reference) else ""
    controller.logger.info(f"{topic}: {len(reference.times)} points until t = {reference.end_time:.3f} s; "
                           f"driving from it{goes_on}")
    return True


def controller_state_topic(base: str) -> str:
    """``~/controller_state`` of controller ``base`` (JTC's state topic)."""
    return f"{base}/controller_state"


def goal_event_topic(base: str) -> str:
    """The ``send_goal`` service's event topic of the action of controller ``base`` (action introspection)."""
    return f"{base}/follow_joint_trajectory/_action/send_goal/_service_event"


def _times(info: Any) -> Times:
    """A subscription's MessageInfo as ``(sent, received)`` seconds (None where the middleware gives none)."""
    sent, received = info.get("source_timestamp") or 0, info.get("received_timestamp") or 0
    return (sent * 1e-9 or None, received * 1e-9 or None)


class FollowJointTrajectoryServer:
    """The action server of ``controller``, its topic trajectories, ``~/query_state`` and its
    state publisher, in a thread of their own."""

    def __init__(self, controller: ControllerView, *, parameter_overrides: Sequence[Parameter] = (),
                 takes_topic: bool | None = None, event_sink: Callable[[bytes], None] | None = None,
                 state_sink: Callable[[bytes], None] | None = None, report: Diagnostics | None = None) -> None:
        self.controller = controller
        base = controller.base
        self.node = Node(f"{controller.name}_action", namespace=controller.namespace, context=controller.context,
                         use_global_arguments=False, start_parameter_services=False, enable_rosout=False,
                         parameter_overrides=parameter_overrides)
        # one "controller: trajectories" status per controller: the node's, when it takes trajectories too
        self.report = report if report is not None else Diagnostics(self.node, "controller: trajectories",
                                                                    controller.robot, logger=controller.logger)
        group = ReentrantCallbackGroup()
        self.server = ActionServer(self.node, FollowJointTrajectory, f"{base}/follow_joint_trajectory",
                                   execute_callback=self.execute, goal_callback=self.on_goal,
                                   handle_accepted_callback=self.on_accepted,
                                   cancel_callback=self.on_cancel, callback_group=group)
        self.node.create_service(QueryTrajectoryState, f"{base}/query_state", self.query_state, callback_group=group)
        # ~/joint_trajectory: here by default in real time; lockstep, the loop takes them (it computes the
        # waiting step at once); in the goal process, the controller's process takes them and hands them over
        if (not controller.lockstep) if takes_topic is None else takes_topic:
            self.node.create_subscription(
                JointTrajectory, controller.resolve(topics.TOPIC_JOINT_TRAJECTORY),
                lambda msg, info: topic_trajectory(controller, msg, _times(info), self.report), topics.TRAJECTORY_QOS,
                callback_group=group)
        self.state = StatePublisher(self.node, controller, sink=state_sink)
        introspection = controller.action_introspection
        # the goal process hands its events (serialized) to the controller's process, which publishes
        # them: a publisher in the child's own participant lost a recorder's first event
        self.event_sink = event_sink
        self.goal_events = None if introspection == "disabled" or event_sink is not None else \
            self.node.create_publisher(FollowJointTrajectory.Impl.SendGoalService.Event, goal_event_topic(base), 10)
        self.introspection = introspection
        self.goal_contents = introspection == "contents"
        self.goal_event_count = 0
        self.pending: dict[int, tuple[Any, GoalExecution]] = {}  # validated, not yet accepted: by id(request)
        self.goals: dict[bytes, tuple[Any, GoalExecution]] = {}  # active goals: (handle, execution)
        if controller.lockstep:  # no deadlines: a timer here; real time: the loop's spare time (idle)
            self.node.create_timer(1.0 / FEEDBACK_HZ, lambda: self.publish(float("inf")), callback_group=group)
        self.executor = MultiThreadedExecutor(num_threads=3, context=controller.context)
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
    def on_goal(self, request: Any) -> GoalResponse:
        """Validate a goal as it arrives (JTC's ``goal_received_callback``): accepted or rejected."""
        ctl = self.controller
        if not ctl.active:  # joint_trajectory_controller: only a running controller accepts
            self.report.report("error", "action goal rejected: the controller is not active")
            return GoalResponse.REJECT
        trajectory = request.trajectory
        checked = ctl.check_goal(
            *trajectory_fields(trajectory), ctl.now(),
            [(t.name, t.position, t.velocity, t.acceleration) for t in request.path_tolerance],
            [(t.name, t.position, t.velocity, t.acceleration) for t in request.goal_tolerance],
            _seconds(request.goal_time_tolerance))
        if not isinstance(checked.goal, GoalExecution):
            self.report.report("error", f"action goal rejected: {checked.goal.error_string}")
            return GoalResponse.REJECT
        if checked.warning:
            ctl.logger.warn(checked.warning)
        if len(self.pending) >= PENDING_KEPT:
            self.pending.clear()
        self.pending[id(request)] = (request, checked.goal)  # rclpy hands this very object to the handle
        return GoalResponse.ACCEPT

    def on_accepted(self, goal_handle: Any) -> None:
        """An accepted goal drives from now on (JTC's ``goal_accepted_callback``: the active goal is
        preempted), then its execute callback watches it."""
        _, execution = self.pending.pop(id(goal_handle.request), (None, None))
        ctl, log = self.controller, self.controller.logger
        if execution is not None:
            key = bytes(goal_handle.goal_id.uuid)
            self.goals[key] = (goal_handle, execution)  # its feedback: publish()
            if not ctl.active:
                execution.finish(Outcome("aborted", INVALID_GOAL, "the controller is not active"))
            elif ctl.start_goal(key, execution):
                log.info("the active action goal was preempted by a new one")
            if execution.outcome is None:
                log.info(f"action goal accepted: {len(execution.reference.times)} points until "
                         f"t = {execution.reference.end_time:.3f} s")
        self.publish_goal_events(goal_handle)
        goal_handle.execute()

    def publish_goal_events(self, goal_handle: Any) -> None:
        """An accepted goal as the ``send_goal`` service's REQUEST_RECEIVED and RESPONSE_SENT
        events (``action_introspection``: with the goal and the answer if ``contents``)."""
        if self.introspection == "disabled":
            return
        service = FollowJointTrajectory.Impl.SendGoalService
        stamp = self.node.get_clock().now().to_msg()
        request = service.Request(goal_id=goal_handle.goal_id, goal=goal_handle.request)
        response = service.Response(accepted=True, stamp=stamp)
        for kind, field, value in ((ServiceEventInfo.REQUEST_RECEIVED, "request", request),
                                   (ServiceEventInfo.RESPONSE_SENT, "response", response)):
            event = service.Event(info=ServiceEventInfo(event_type=kind, stamp=stamp,
                                                        sequence_number=self.goal_event_count))
            if self.goal_contents:
                setattr(event, field, [value])
            if self.event_sink is not None:
                self.event_sink(serialize_message(event))
            elif self.goal_events is not None:
                self.goal_events.publish(event)
        self.goal_event_count += 1

    def on_cancel(self, goal_handle: Any) -> CancelResponse:
        key = bytes(goal_handle.goal_id.uuid)
        found = self.goals.get(key)
        if found is not None and self.controller.cancel_goal(key, found[1]):
            self.controller.logger.info("action goal canceled: holding")
        return CancelResponse.ACCEPT

    def execute(self, goal_handle: Any) -> FollowJointTrajectory.Result:
        key = bytes(goal_handle.goal_id.uuid)
        found = self.goals.get(key)
        if found is None:  # not validated here (cannot happen: every accepted goal is)
            goal_handle.abort()
            return FollowJointTrajectory.Result(error_code=INVALID_GOAL, error_string="goal not validated")
        execution = found[1]
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

    # -- ~/query_state -------------------------------------------------------- #
    def query_state(self, request: Any, response: Any) -> Any:
        """The running trajectory's reference at ``request.time`` (JTC's ``query_state_service``):
        ``success`` False when the controller is not active, holds a position, or the time lies
        before the trajectory's start or at or after its last point."""
        ctl = self.controller
        response.name = list(ctl.joints)
        if not ctl.active:
            response.success, response.message = False, "Can't sample trajectory. Controller is not active."
            return response
        trajectory = ctl.driving()
        t = _seconds(request.time)
        if not isinstance(trajectory, JointTrajectoryReference):
            response.success, response.message = False, "Currently there is no valid trajectory instance."
        elif t < trajectory.start_time:
            response.success, response.message = False, ("Requested sample time is earlier than the current "
                                                         "trajectory start time.")
        elif not trajectory.covers(t):
            response.success, response.message = False, ("Requested sample time is at or after the current "
                                                         "trajectory's end time.")
        else:
            to_user = ctl.joint_map.to_user
            q, qd, qdd = (to_user(np.asarray(v, dtype=float)).tolist() for v in trajectory.sample(t))
            response.success, response.position, response.velocity, response.acceleration = True, q, qd, qdd
        return response

    def publish(self, until: float) -> None:
        """The controller state and the active goals' feedback (:meth:`StatePublisher.publish`)."""
        self.state.publish(until, list(self.goals.values()))
