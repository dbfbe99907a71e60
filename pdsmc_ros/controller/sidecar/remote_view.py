"""The controller as the goal process's action server sees it (:class:`RemoteView`): goals
validated in the child as the controller would validate them, carried out by the loop's process
(:class:`~.goal_process.GoalProcess`) over the pipe (:mod:`.framing`)."""

from __future__ import annotations

import collections
import threading
from collections.abc import Callable, Sequence
from typing import Any

from ..goals import GoalExecution, GoalSettings
from ..joint_trajectory import JointTrajectoryReference, RawPoint
from ..limits import JointLimits
from .goal_process import KEPT_TRAJECTORIES

MEASURE_WAIT_S = 1.0  # the child waits this long for the loop's latest state when a goal arrives


class RemoteView:
    """The controller as the action server sees it in the goal process
    (:class:`~pdsmc_ros.controller.action.ControllerView`): goals validated here, carried out by the loop's process."""

    def __init__(self, setup: dict[str, Any], context: Any, send: Callable[[object], None]) -> None:
        import rclpy.logging

        from ..joints import JointSelector

        self.name, self.namespace, self.base = setup["name"], setup["namespace"], setup["base"]
        self.context = context
        self.logger = rclpy.logging.get_logger(self.name)
        self.robot = setup["spec"].robot
        self.joints = setup["joints"]
        self.joint_map = setup["joint_map"]
        self.action_introspection = setup["action_introspection"]
        self.lockstep = False
        self.active = False
        self.topics = setup["topics"]
        self.limits: JointLimits | None = setup["limits"]
        self.settings: GoalSettings = setup["goal_settings"]
        self.selector = JointSelector(setup["robot_joints"])
        self.send = send
        self.latched = ""  # the runaway stop's reason while latched
        self.snapshot: tuple[Any, ...] | None = None
        self.clamped = 0
        self.started: dict[bytes, GoalExecution] = {}  # sent to the loop, their end not yet known
        self.trajectories: collections.OrderedDict[object, JointTrajectoryReference] = collections.OrderedDict()
        self.driving_now: tuple[object, float, float] | None = None
        self.topic_count = 0
        self.clock: Any = None  # the action server's node's (its use_sim_time is the controller's)
        self.asking = threading.Lock()
        self.answered = threading.Event()
        self.answer: tuple[Any, Any] | None = None
        self.lock = threading.Lock()  # the executor's threads and the reader thread

    def now(self) -> float:
        return self.clock.now().nanoseconds * 1e-9

    def resolve(self, topic: str) -> str:
        return self.topics[topic]

    def measured(self) -> tuple[Any, Any] | None:
        """The controller's latest complete measured state ``(q, qd)`` (robot order), asked of the
        loop's process -- the very state its own checks would use, as joint_trajectory_controller's
        -- or, if it does not answer within :data:`MEASURE_WAIT_S` (a loop with no spare time), the
        one of its latest period; None before the first."""
        with self.asking:  # one question at a time (the executor's threads)
            self.answered.clear()
            self.send(("measure",))
            if self.answered.wait(MEASURE_WAIT_S):
                return self.answer
            snapshot = self.snapshot
            return None if snapshot is None else (snapshot[1], snapshot[2])

    def check_goal(self, stamp: float, names: Sequence[str], points: Sequence[RawPoint], effort_sizes: Sequence[int],
                   now: float, path: Sequence[Any], goal: Sequence[Any], goal_time: float) -> Any:
        from ..core import check_goal

        return check_goal(self.settings, self.limits, self.selector.joints, self.measured(), self.latched_reason(),
                          stamp, names, points, effort_sizes, now, path, goal, goal_time)

    def check_topic_trajectory(self, stamp: float, names: Sequence[str], points: Sequence[RawPoint],
                               effort_sizes: Sequence[int], times: Any, now: float
                               ) -> tuple[JointTrajectoryReference | None, str]:
        from ..core import check_topic_trajectory

        return check_topic_trajectory(self.settings, self.limits, self.selector.joints, self.measured(),
                                      self.latched_reason(), False, stamp, names, points, effort_sizes, times, now)

    def latched_reason(self) -> str:
        from ..core import latched_refusal

        return latched_refusal(self.latched)

    def _running_goal(self) -> bool:
        return any(execution.outcome is None for execution in self.started.values())

    def start_goal(self, key: bytes, execution: GoalExecution) -> bool:
        with self.lock:
            preempts = self._running_goal()
            self.started[key] = execution
            self._remember(key, execution.reference)
        self.send(("start", key, execution))
        return preempts

    def cancel_goal(self, key: bytes, execution: GoalExecution) -> bool:
        if execution.outcome is not None:
            return False
        self.send(("cancel", key))
        return True

    def follow(self, reference: JointTrajectoryReference) -> bool:
        with self.lock:
            self.topic_count += 1
            tid = self.topic_count
            self._remember(tid, reference)
            goes_on = self._running_goal()
        self.send(("follow", tid, reference))
        return goes_on

    def _remember(self, tid: object, reference: JointTrajectoryReference) -> None:
        self.trajectories[tid] = reference
        while len(self.trajectories) > KEPT_TRAJECTORIES:
            self.trajectories.popitem(last=False)

    def driving(self) -> JointTrajectoryReference | None:
        with self.lock:
            if self.driving_now is None:
                return None
            tid, start, end = self.driving_now
            reference = self.trajectories.get(tid)
            if reference is not None:  # the loop starts a goal stamped 0 at its first sample of it
                reference.start_time, reference.end_time = start, end
            return reference

    def latest(self) -> tuple[tuple[Any, ...] | None, int]:
        return self.snapshot, self.clamped

    def hear(self, message: Any) -> bool:
        """A message from the loop's process; whether the state publisher has news to send."""
        kind = message[0]
        if kind == "active":
            self.active = bool(message[1])
        elif kind == "runaway":
            self.latched = str(message[1])
        elif kind == "ended":
            with self.lock:
                execution = self.started.pop(message[1], None)
            if execution is not None:
                execution.finish(message[2])
        elif kind == "measured":
            self.answer = message[1]
            self.answered.set()
        elif kind == "driving":
            with self.lock:
                self.driving_now = None if message[1] is None else (message[1], message[2], message[3])
        elif kind == "state":
            _, self.snapshot, self.clamped, feedback = message
            with self.lock:
                for key, value in feedback.items():
                    execution = self.started.get(key)
                    if execution is not None:
                        execution.feedback = value
            return True
        return False
