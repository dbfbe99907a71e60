"""A FollowJointTrajectory client: what ``ros2 action send_goal`` does, for any such server.

:func:`goal_message` builds ``control_msgs/action/FollowJointTrajectory``'s goal from a goal
file's data (:mod:`pdsmc_ros.contours.goal_file`); :func:`send_goal` sends it from a plain
rclpy node of its own (:class:`~.spun_node.SpunNode`: a context of its own, so no rclpy signal
handler -- Ctrl-C reaches Python), reports progress from the server's feedback, waits for the
result and cancels the goal on Ctrl-C, as ``ros2 action send_goal`` does.

An accepted goal succeeded when it ends ``SUCCEEDED`` with ``error_code`` 0 (``SUCCESSFUL``);
anything else -- rejected, aborted, canceled, an error code -- is a failure (:class:`GoalOutcome`).
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

from action_msgs.msg import GoalStatus
from builtin_interfaces.msg import Duration, Time
from control_msgs.action import FollowJointTrajectory
from control_msgs.msg import JointTolerance
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from .spun_node import SpunNode

__all__ = ["ERROR_CODES", "GoalOutcome", "goal_message", "send_goal"]

ERROR_CODES = {0: "SUCCESSFUL", -1: "INVALID_GOAL", -2: "INVALID_JOINTS", -3: "OLD_HEADER_TIMESTAMP",
               -4: "PATH_TOLERANCE_VIOLATED", -5: "GOAL_TOLERANCE_VIOLATED"}
"""``FollowJointTrajectory.Result.error_code``'s names."""
STATUS_NAMES = {GoalStatus.STATUS_SUCCEEDED: "SUCCEEDED", GoalStatus.STATUS_ABORTED: "ABORTED",
                GoalStatus.STATUS_CANCELED: "CANCELED", GoalStatus.STATUS_UNKNOWN: "UNKNOWN"}
PROGRESS_EVERY_S = 1.0
"""Seconds between two progress lines."""
CANCEL_WAIT_S = 10.0
"""How long a canceled goal's result is waited for."""
SERVER_CHECK_S = 0.5
"""Seconds between two looks, during a goal, at whether its server is still there."""


def _duration(value: Mapping[str, Any]) -> Duration:
    return Duration(sec=int(value["sec"]), nanosec=int(value["nanosec"]))


def goal_message(data: Mapping[str, Any]) -> FollowJointTrajectory.Goal:
    """The goal of a goal file's checked data (:func:`~pdsmc_ros.contours.goal_file.read_goal`)."""
    trajectory = data["trajectory"]
    header = trajectory.get("header", {})
    msg = JointTrajectory()
    stamp = header.get("stamp", {"sec": 0, "nanosec": 0})
    msg.header.stamp = Time(sec=int(stamp["sec"]), nanosec=int(stamp["nanosec"]))
    msg.header.frame_id = str(header.get("frame_id", ""))
    msg.joint_names = list(trajectory["joint_names"])
    for point in trajectory["points"]:
        msg.points.append(JointTrajectoryPoint(
            positions=[float(v) for v in point.get("positions", [])],
            velocities=[float(v) for v in point.get("velocities", [])],
            accelerations=[float(v) for v in point.get("accelerations", [])],
            effort=[float(v) for v in point.get("effort", [])],
            time_from_start=_duration(point["time_from_start"])))
    goal = FollowJointTrajectory.Goal(trajectory=msg)
    for key in ("path_tolerance", "goal_tolerance"):
        setattr(goal, key, [JointTolerance(name=t["name"], position=float(t.get("position", 0.0)),
                                           velocity=float(t.get("velocity", 0.0)),
                                           acceleration=float(t.get("acceleration", 0.0))) for t in data.get(key, [])])
    goal.goal_time_tolerance = _duration(data.get("goal_time_tolerance", {"sec": 0, "nanosec": 0}))
    return goal


@dataclass(frozen=True)
class GoalOutcome:
    """How a goal ended.

    Attributes
    ----------
    accepted : bool
    status : str
        The goal's final status (``SUCCEEDED``, ``ABORTED``, ``CANCELED``; ``REJECTED`` if not accepted,
        ``NO_SERVER`` if no server answered, ``NO_RESULT`` if none came).
    error_code : int or None
    error_string : str
    canceled_by_user : bool
        Ctrl-C canceled it.
    """

    accepted: bool
    status: str
    error_code: int | None
    error_string: str
    canceled_by_user: bool = False

    @property
    def succeeded(self) -> bool:
        return self.status == "SUCCEEDED" and self.error_code == 0

    def describe(self) -> str:
        reason = f": {self.error_string}" if self.error_string else ""
        if not self.accepted:
            return f"goal {self.status.lower().replace('_', ' ')}{reason}"
        code = "" if self.error_code is None else \
            f", error_code {self.error_code} ({ERROR_CODES.get(self.error_code, 'unknown')})"
        return f"result: {self.status}{code}{reason}"


def _seconds(d: Duration) -> float:
    return float(d.sec) + 1e-9 * float(d.nanosec)


class ServerWatch:
    """Whether an action server has been gone for ``patience`` seconds (``ready``: the client's
    ``server_is_ready``, asked every :data:`SERVER_CHECK_S`).

    A result is requested once; if the server's process ends, nothing will ever answer it, and a
    client that waits only for the result waits forever. Brief absences are tolerated: a server
    restarting its goal process is away for a second or two.
    """

    def __init__(self, ready: Callable[[], bool], patience: float, *,
                 clock: Callable[[], float] = time.monotonic) -> None:
        if not patience >= 0.0 or patience == float("inf"):
            raise ValueError(f"patience must be a finite number of seconds >= 0, got {patience!r}")
        self.ready = ready
        self.patience = float(patience)
        self.clock = clock
        self.next_check = clock()
        self.away_since: float | None = None

    def gone(self) -> bool:
        now = self.clock()
        if now < self.next_check:
            return False
        self.next_check = now + SERVER_CHECK_S
        if self.ready():
            self.away_since = None
            return False
        if self.away_since is None:
            self.away_since = now
        return now - self.away_since >= self.patience


def send_goal(goal: FollowJointTrajectory.Goal, action: str, *, server_timeout: float = 10.0,
              progress: Callable[[str], None] | None = None, domain: int | None = None) -> GoalOutcome:
    """Send ``goal`` to the FollowJointTrajectory server ``action`` and wait for its result; Ctrl-C
    (KeyboardInterrupt) cancels the goal, waits for the canceled result and returns it.

    ``progress`` receives a line per :data:`PROGRESS_EVERY_S` from the feedback: the goal's time
    and the largest position error. ``domain``: the ROS domain (default ``ROS_DOMAIN_ID``, else 0).
    A server that goes away during the goal and stays away ``server_timeout`` seconds ends the wait
    with ``NO_RESULT`` (:class:`ServerWatch`).
    """
    from rclpy.action import ActionClient

    say = progress or (lambda _line: None)
    end = max((_seconds(p.time_from_start) for p in goal.trajectory.points), default=0.0)
    client = SpunNode(int(os.environ.get("ROS_DOMAIN_ID", "0")) if domain is None else domain, "pdsmc_send_goal")
    try:
        action_client = ActionClient(client.node, FollowJointTrajectory, action)
        if not action_client.wait_for_server(timeout_sec=server_timeout):
            return GoalOutcome(False, "NO_SERVER", None, f"no FollowJointTrajectory server on {action} within "
                               f"{server_timeout:g} s")
        last = [0.0]

        def on_feedback(message: Any) -> None:
            now = time.monotonic()
            if now - last[0] < PROGRESS_EVERY_S:
                return
            last[0] = now
            fb = message.feedback
            errors = [abs(e) for e in fb.error.positions]
            worst = max(range(len(errors)), key=errors.__getitem__) if errors else None
            error = f", largest position error {errors[worst]:.3g} ({fb.joint_names[worst]})" \
                if worst is not None and worst < len(fb.joint_names) else ""
            at = _seconds(fb.desired.time_from_start)
            say(f"t = {at:.1f} / {end:.1f} s{error}")

        try:
            handle = client.call(lambda: action_client.send_goal_async(goal, feedback_callback=on_feedback),
                                 seconds=server_timeout)
        except TimeoutError:
            return GoalOutcome(False, "NO_ANSWER", None, f"the server on {action} did not answer the goal within "
                               f"{server_timeout:g} s")
        if not handle.accepted:
            return GoalOutcome(False, "REJECTED", None, f"the server on {action} rejected the goal (its log says why)")
        say(f"goal accepted by {action}: {len(goal.trajectory.points)} points over {end:.3g} s")
        result_future = handle.get_result_async()
        canceled = False
        lost = ServerWatch(action_client.server_is_ready, server_timeout)
        try:
            while not result_future.done():
                time.sleep(0.02)
                if lost.gone():
                    return GoalOutcome(True, "NO_RESULT", None, f"the server on {action} went away during the goal "
                                       f"and sent no result (gone for {server_timeout:g} s)")
        except KeyboardInterrupt:
            canceled = True
            say("Ctrl-C: canceling the goal")
            client.call(lambda: handle.cancel_goal_async(), seconds=CANCEL_WAIT_S)
            client.wait(result_future.done, CANCEL_WAIT_S)
        if not result_future.done():
            return GoalOutcome(True, "NO_RESULT", None, "the server sent no result", canceled)
        answer = result_future.result()
        status = STATUS_NAMES.get(answer.status, str(answer.status))
        return GoalOutcome(True, status, int(answer.result.error_code), str(answer.result.error_string), canceled)
    finally:
        client.close()
