"""FollowJointTrajectory goals as joint_trajectory_controller executes them. ROS-free.

The semantics are those of ros2_controllers' joint_trajectory_controller
(``joint_trajectory_controller.cpp``: ``update``, ``goal_received_callback``,
``preempt_active_goal``; ``tolerances.hpp``):

- validation: the goal names every controlled joint and no other
  (INVALID_JOINTS), its points are well formed (INVALID_GOAL), a non-zero
  ``header.stamp`` does not end the trajectory in the past (OLD_HEADER_TIMESTAMP);
  here also: it stays within the arm's limits (INVALID_GOAL naming joint, point, time);
- tolerances per joint (``path_tolerance``, ``goal_tolerance``: position and
  velocity; 0 keeps the default, -1 erases it, any other negative value is
  illegal and the defaults apply) and ``goal_time_tolerance``;
- every control period before the last point's time: a path-tolerance breach
  aborts with PATH_TOLERANCE_VIOLATED (the controller then holds where the arm is);
- from the last point's time on: within the goal tolerances it succeeds; outside
  them once ``goal_time_tolerance`` (if not 0) has passed it aborts with
  GOAL_TOLERANCE_VIOLATED (and holds); otherwise it keeps waiting;
- a new goal preempts the active one: aborted with INVALID_GOAL, "Current goal
  preempted by new incoming action."; a cancel ends it as canceled (and holds).

A ROS 2 rejection carries no result, so a goal that fails validation is accepted
and at once aborted with its code and reason (it never moves the arm): a
client sees why. Errors are ``desired - actual`` (the controller's ``error``).
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from .joint_trajectory import JointTrajectoryReference, RawPoint
from .joints import JointSelector
from .limits import JointLimits

FloatArray = np.ndarray

# control_msgs/action/FollowJointTrajectory Result.error_code
SUCCESSFUL = 0
INVALID_GOAL = -1
INVALID_JOINTS = -2
OLD_HEADER_TIMESTAMP = -3
PATH_TOLERANCE_VIOLATED = -4
GOAL_TOLERANCE_VIOLATED = -5

ERASE = -1.0  # a tolerance of -1 erases the default (JointTolerance.msg)
STOPPED_VELOCITY_TOLERANCE = 0.01  # rad/s: joint_trajectory_controller's default goal velocity tolerance


@dataclass(frozen=True)
class Outcome:
    """How a goal ended: ``status`` is ``succeeded``, ``aborted`` or ``canceled``."""

    status: str
    error_code: int
    error_string: str


PREEMPTED = Outcome("aborted", INVALID_GOAL, "Current goal preempted by new incoming action.")
CANCELED = Outcome("canceled", SUCCESSFUL, "Goal canceled: holding the position at the cancel.")


@dataclass(frozen=True)
class Tolerances:
    """Per joint in robot order (0: not enforced): path and goal position (rad) and velocity
    (rad/s), and ``goal_time`` (s, 0: wait for the goal tolerances as long as it takes)."""

    path_position: FloatArray
    path_velocity: FloatArray
    goal_position: FloatArray
    goal_velocity: FloatArray
    goal_time: float = 0.0

    @classmethod
    def defaults(cls, n: int, *, stopped_velocity: float = STOPPED_VELOCITY_TOLERANCE,
                 goal_time: float = 0.0) -> Tolerances:
        """joint_trajectory_controller's defaults: no path or goal position tolerance, the
        stopped-velocity tolerance at the goal, no goal time limit."""
        zero = np.zeros(n)
        return cls(zero, zero.copy(), zero.copy(), np.full(n, stopped_velocity), goal_time)


def _resolve(default: float, given: float) -> float:
    """``tolerances.hpp`` resolve_tolerance_source: > 0 replaces, -1 erases, 0 keeps, else illegal."""
    if given > 0.0:
        return given
    if abs(given - ERASE) < 1.2e-7:  # float epsilon, as the controller compares
        return 0.0
    if given < 0.0:
        raise ValueError(given)
    return default


def resolve_tolerances(defaults: Tolerances, robot_joints: Sequence[str],
                       path: Sequence[tuple[str, float, float]], goal: Sequence[tuple[str, float, float]],
                       goal_time: float) -> tuple[Tolerances, str]:
    """The goal's tolerances over ``defaults`` (``(name, position, velocity)`` entries).

    Returns ``(tolerances, warning)``: as joint_trajectory_controller, an unknown
    joint or an illegal value keeps the defaults, with a warning naming it.
    """
    try:
        time_tolerance = _resolve(defaults.goal_time, goal_time)
    except ValueError:
        return defaults, f"illegal goal_time_tolerance {goal_time:g} s: default tolerances used"
    arrays = {"path": [defaults.path_position.copy(), defaults.path_velocity.copy()],
              "goal": [defaults.goal_position.copy(), defaults.goal_velocity.copy()]}
    for kind, entries in (("path", path), ("goal", goal)):
        for name, position, velocity in entries:
            if name not in robot_joints:
                return defaults, (f"joint {name!r} in goal.{kind}_tolerance is not a controlled joint "
                                  f"({list(robot_joints)}): default tolerances used")
            i = robot_joints.index(name)
            for column, value, what in ((0, position, "position"), (1, velocity, "velocity")):
                try:
                    arrays[kind][column][i] = _resolve(arrays[kind][column][i], value)
                except ValueError:
                    return defaults, (f"joint {name!r} in goal.{kind}_tolerance has an illegal {what} "
                                      f"tolerance {value:g}: default tolerances used")
    (path_q, path_qd), (goal_q, goal_qd) = arrays["path"], arrays["goal"]
    return Tolerances(path_q, path_qd, goal_q, goal_qd, time_tolerance), ""


def validate_goal(selector: JointSelector, stamp: float, names: Sequence[str], points: Sequence[RawPoint],
                  now: float, state: tuple[FloatArray, FloatArray] | None, limits: JointLimits | None
                  ) -> tuple[JointTrajectoryReference | None, Outcome | None]:
    """A goal's trajectory as a reference from ``now`` and the measured ``state``, or the
    outcome of an invalid goal (its code and reason).

    ``limits`` None: no limit check (``enforce_limits:=false``).
    """
    names = tuple(names)
    controlled = selector.joints
    unknown = [name for name in names if name not in controlled]
    missing = [name for name in controlled if name not in names]
    if unknown or missing or not names:
        what = (f"joint {unknown[0]!r} is not controlled" if unknown
                else f"joint {missing[0]!r} is missing" if missing else "no joint_names")
        return None, Outcome("aborted", INVALID_JOINTS,
                             f"{what}: a goal names every controlled joint, {list(controlled)}, and no other")
    if state is None:
        return None, Outcome("aborted", INVALID_GOAL, "no complete joint state yet (the motion starts from it)")
    if points and points[-1][1] and any(abs(v) > 1.2e-7 for v in points[-1][1]):
        return None, Outcome("aborted", INVALID_GOAL, "the last point's velocities are not zero")
    reference, problem = JointTrajectoryReference.from_message(selector, stamp, names, points, now, *state)
    if reference is None:
        code = OLD_HEADER_TIMESTAMP if "before it was received" in problem else INVALID_GOAL
        return None, Outcome("aborted", code, problem)
    if limits is not None:
        problem = limits.trajectory_problem(reference)
        if problem:
            return None, Outcome("aborted", INVALID_GOAL, f"refused: {problem}")
    return reference, None


@dataclass
class Feedback:
    """The latest control period of a goal (robot order): its time, desired, actual and error."""

    time: float
    desired: tuple[FloatArray, FloatArray, FloatArray]
    actual: tuple[FloatArray, FloatArray]
    error: tuple[FloatArray, FloatArray]


@dataclass
class GoalExecution:
    """One accepted goal, checked every control period by :meth:`update` (the control loop)
    and watched by the action server's thread (:attr:`done`, :attr:`outcome`, :attr:`feedback`).

    Parameters
    ----------
    reference : JointTrajectoryReference
        The goal's trajectory on the controller's clock.
    tolerances : Tolerances
        Resolved per joint (robot order).
    names : tuple of str
        The joints in robot order (for the reasons given).
    """

    reference: JointTrajectoryReference
    tolerances: Tolerances
    names: tuple[str, ...]
    outcome: Outcome | None = None
    feedback: Feedback | None = None
    done: threading.Event = field(default_factory=threading.Event)
    first_sample: bool = True

    def update(self, t: float, q: FloatArray, qd: FloatArray,
               desired: tuple[FloatArray, FloatArray, FloatArray]) -> Outcome | None:
        """Check one control period at time ``t``; the outcome once the goal ends here, else None."""
        if self.outcome is not None:
            return None
        q, qd = np.asarray(q, dtype=float), np.asarray(qd, dtype=float)
        error_q, error_qd = desired[0] - q, desired[1] - qd
        self.feedback = Feedback(t, desired, (q, qd), (error_q, error_qd))
        tol = self.tolerances
        late = t - self.reference.end_time  # >= 0: at or past the last point
        if late < 0.0 or self.first_sample:
            # the first sample is checked too, in case it is already the last point
            self.first_sample = False
            joint = _outside(error_q, error_qd, tol.path_position, tol.path_velocity)
            if joint >= 0:
                why = _describe(self.names[joint], joint, error_q, error_qd)
                return self.finish(Outcome("aborted", PATH_TOLERANCE_VIOLATED,
                                           f"Aborted due to path tolerance violation: {why}"))
        if late < 0.0:
            return None
        joint = _outside(error_q, error_qd, tol.goal_position, tol.goal_velocity)
        if joint < 0:
            return self.finish(Outcome("succeeded", SUCCESSFUL, "Goal successfully reached!"))
        if tol.goal_time != 0.0 and late > tol.goal_time:
            why = _describe(self.names[joint], joint, error_q, error_qd)
            return self.finish(Outcome("aborted", GOAL_TOLERANCE_VIOLATED,
                                       f"Aborted due to goal_time_tolerance exceeding by {late:.6f} seconds: {why}"))
        return None

    def finish(self, outcome: Outcome) -> Outcome | None:
        """End the goal with ``outcome`` unless it already ended; the outcome if it ended now."""
        if self.outcome is not None:
            return None
        self.outcome = outcome
        self.done.set()
        return outcome


def _outside(error_q: FloatArray, error_qd: FloatArray, position: FloatArray, velocity: FloatArray) -> int:
    """The first joint outside its (enforced, > 0) tolerances, or -1."""
    bad = ((position > 0.0) & (np.abs(error_q) > position)) | ((velocity > 0.0) & (np.abs(error_qd) > velocity))
    return int(np.argmax(bad)) if bad.any() else -1


def _describe(name: str, joint: int, error_q: FloatArray, error_qd: FloatArray) -> str:
    return (f"joint {name!r}: position error {error_q[joint]:.6g} rad, "
            f"velocity error {error_qd[joint]:.6g} rad/s")


class GoalSlot:
    """The controller's one active goal, shared by the control loop and the action server's thread.

    The action thread :meth:`start` s and :meth:`cancel` s goals; the loop :meth:`check` s the
    active one every period. One lock orders them, so a hold decided by the loop never
    replaces a goal the action thread has just started, and the reverse.

    Parameters
    ----------
    drive : callable
        ``drive(reference)``: make ``reference`` the controller's reference from now on.
    hold : callable
        ``hold(why)``: hold the latest measured position from now on.
    """

    def __init__(self, drive: Callable[[object], None], hold: Callable[[str], None]) -> None:
        self.lock = threading.Lock()
        self.active: GoalExecution | None = None
        self._drive = drive
        self._hold = hold

    def start(self, goal: GoalExecution) -> GoalExecution | None:
        """Drive ``goal`` from now on; the goal it preempted (aborted, INVALID_GOAL), if any."""
        with self.lock:
            old = self.active
            if old is not None and old.finish(PREEMPTED) is None:
                old = None  # it had ended already
            self.active = goal
            self._drive(goal.reference)
        return old

    def cancel(self, goal: GoalExecution) -> bool:
        """Cancel ``goal`` if it is the active one and hold where the arm is; whether it was."""
        with self.lock:
            if self.active is not goal or goal.finish(CANCELED) is None:
                return False
            self.active = None
            self._hold("goal canceled")
            return True

    def end(self, why: str) -> GoalExecution | None:
        """The controller stops (deactivated): the active goal, if any, ends aborted (INVALID_GOAL)."""
        with self.lock:
            old, self.active = self.active, None
            if old is not None and old.finish(Outcome("aborted", INVALID_GOAL, why)) is not None:
                return old
            return None

    def replace(self, reference: object, why: str) -> GoalExecution | None:
        """``reference`` (a topic trajectory) drives from now on; the active goal, if any, ends
        aborted with INVALID_GOAL and ``why`` (returned)."""
        with self.lock:
            old, self.active = self.active, None
            self._drive(reference)
            if old is not None and old.finish(Outcome("aborted", INVALID_GOAL, why)) is not None:
                return old
            return None

    def check(self, t: float, q: FloatArray, qd: FloatArray,
              desired: tuple[FloatArray, FloatArray, FloatArray]) -> tuple[Outcome | None, bool]:
        """The loop's period at time ``t``: ``(outcome if the active goal ended now, whether
        the controller holds from now on)``. A violated goal holds the arm where it is (the
        caller recomputes this period's reference); a reached one holds its last point by
        itself (the trajectory's end)."""
        goal = self.active
        if goal is None:
            return None, False
        with self.lock:
            if self.active is not goal:
                return None, False
            outcome = goal.update(t, q, qd, desired)
            if outcome is None:
                return None, False
            self.active = None
            if outcome.status == "aborted":
                self._hold(outcome.error_string)
                return outcome, True
            return outcome, False
