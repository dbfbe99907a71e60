"""FollowJointTrajectory goals and topic trajectories as joint_trajectory_controller executes them. ROS-free.

The semantics are those of ros2_controllers' joint_trajectory_controller (Jazzy, 4.x:
``joint_trajectory_controller.cpp``: ``goal_received_callback``, ``validate_trajectory_msg``,
``goal_accepted_callback``, ``preempt_active_goal``, ``goal_cancelled_callback``, ``update``;
``tolerances.hpp``):

- validation when a goal or a topic trajectory arrives (:func:`prepare_trajectory`: the
  rules of :func:`~.joint_trajectory.check_trajectory`); a goal that fails is rejected
  (no result), a topic trajectory is dropped, the running motion untouched. Beyond JTC,
  and on by default (``reject_beyond_limits``): a trajectory that leaves the arm's position or
  velocity limits, or starts with a step, is refused the same way
  (:class:`~.limits.JointLimits`);
- tolerances per joint (``path_tolerance``, ``goal_tolerance``: position, velocity and
  acceleration; 0 keeps the default, -1 erases it, an unknown joint or any other negative
  value makes the whole goal use the defaults) and ``goal_time_tolerance``; the defaults are
  the ``constraints.*`` parameters, and a goal's tolerances do not outlive it;
- every control period before the last point's time: a path-tolerance breach aborts with
  PATH_TOLERANCE_VIOLATED (the controller then holds where the arm is);
- from the last point's time on: within the goal tolerances it succeeds; outside them once
  ``goal_time_tolerance`` (if not 0) has passed it aborts with GOAL_TOLERANCE_VIOLATED (and
  holds); otherwise it keeps waiting;
- a new goal preempts the active one: aborted with INVALID_GOAL, "Current goal preempted by
  new incoming action."; a cancel ends it CANCELED with an empty error string, holding the
  measured position; a topic trajectory replaces the running trajectory and an active goal
  goes on, judged against the new trajectory;
- a topic trajectory without a goal is checked against the default tolerances too: a breach
  holds the measured position; ``cmd_timeout`` s after its last point (0: never) the
  controller holds the measured position as well;
- errors are ``desired - actual``, the position error of a continuous joint the shortest
  angle (``angles::shortest_angular_distance``).

The controller's acceleration is not measured, so acceleration tolerances are read and
checked for legality but never enforced (JTC without an acceleration state interface does
the same).
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from ..parameters.tables import START_TOLERANCE, STOPPED_VELOCITY_TOLERANCE
from .joint_trajectory import FLOAT_EPSILON, JointTrajectoryReference, RawPoint, TrajectoryRules, check_trajectory
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


@dataclass(frozen=True)
class Outcome:
    """How a goal ended: ``status`` is ``succeeded``, ``aborted`` or ``canceled``."""

    status: str
    error_code: int
    error_string: str


PREEMPTED = Outcome("aborted", INVALID_GOAL, "Current goal preempted by new incoming action.")
CANCELED = Outcome("canceled", SUCCESSFUL, "")  # JTC: a default-constructed result


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
    def defaults(cls, n: int, *, stopped_velocity: float = STOPPED_VELOCITY_TOLERANCE, goal_time: float = 0.0,
                 trajectory: Sequence[float] | None = None, goal: Sequence[float] | None = None) -> Tolerances:
        """joint_trajectory_controller's defaults (``get_segment_tolerances``): the per-joint
        ``constraints.<joint>.trajectory`` and ``.goal`` position tolerances (robot order; none:
        not enforced), no path velocity tolerance, ``constraints.stopped_velocity_tolerance`` at
        the goal, ``constraints.goal_time``."""
        path = np.zeros(n) if trajectory is None else np.asarray(trajectory, dtype=float).copy()
        at_goal = np.zeros(n) if goal is None else np.asarray(goal, dtype=float).copy()
        return cls(path, np.zeros(n), at_goal, np.full(n, stopped_velocity), goal_time)


def _resolve(default: float, given: float) -> float:
    """``tolerances.hpp`` resolve_tolerance_source: > 0 replaces, -1 erases, 0 keeps, else illegal."""
    if given > 0.0:
        return given
    if abs(given - ERASE) < FLOAT_EPSILON:
        return 0.0
    if given < 0.0:
        raise ValueError(given)
    return default


def resolve_tolerances(defaults: Tolerances, robot_joints: Sequence[str],
                       path: Sequence[tuple[str, float, float] | tuple[str, float, float, float]],
                       goal: Sequence[tuple[str, float, float] | tuple[str, float, float, float]],
                       goal_time: float) -> tuple[Tolerances, str]:
    """The goal's tolerances over ``defaults`` (``(name, position, velocity[, acceleration])`` entries).

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
        for name, *values in entries:
            if name not in robot_joints:
                return defaults, (f"joint {name!r} in goal.{kind}_tolerance is not a controlled joint "
                                  f"({list(robot_joints)}): default tolerances used")
            i = robot_joints.index(name)
            for column, (value, what) in enumerate(zip(values, ("position", "velocity", "acceleration"))):
                try:
                    resolved = _resolve(arrays[kind][column][i] if column < 2 else 0.0, value)
                except ValueError:
                    return defaults, (f"joint {name!r} in goal.{kind}_tolerance has an illegal {what} "
                                      f"tolerance {value:g}: default tolerances used")
                if column < 2:  # acceleration is not measured: legal values are not enforced
                    arrays[kind][column][i] = resolved
    (path_q, path_qd), (goal_q, goal_qd) = arrays["path"], arrays["goal"]
    return Tolerances(path_q, path_qd, goal_q, goal_qd, time_tolerance), ""


@dataclass(frozen=True)
class GoalSettings:
    """How the controller takes trajectories (its parameters).

    Parameters
    ----------
    rules : TrajectoryRules
        ``allow_partial_joints_goal``, ``allow_nonzero_velocity_at_trajectory_end``, the size limit.
    defaults : Tolerances
        The ``constraints.*`` parameters (robot order).
    cmd_timeout : float
        Hold the measured position this long after a trajectory's last point (s; 0: never).
        As JTC, it must exceed ``defaults.goal_time`` (else it is 0).
    start_tolerance : float
        Beyond JTC: the largest jump from the measured position to a trajectory's reference at
        receipt that is not a step (rad; MoveIt's ``allowed_start_tolerance``).
    reject_beyond_limits : bool
        Beyond JTC: refuse trajectories that leave the arm's limits or start with a step.
    wrap : ndarray of bool, optional
        Continuous joints (robot order): their position errors are angles wrapped to (-pi, pi].
    stop_deceleration : ndarray, optional
        ``constraints.decelerate_on_cancel``: each joint's deceleration (robot order, rad/s^2) to
        brake at before a cancel's or an abort's hold (:class:`~pdsmc_ros.controller.hold.Stop`);
        None: hold at once.
    """

    rules: TrajectoryRules = field(default_factory=TrajectoryRules)
    defaults: Tolerances | None = None
    cmd_timeout: float = 0.0
    start_tolerance: float = START_TOLERANCE
    reject_beyond_limits: bool = True
    wrap: FloatArray | None = None
    stop_deceleration: FloatArray | None = None

    def __post_init__(self) -> None:
        for name in ("cmd_timeout", "start_tolerance"):
            value = getattr(self, name)
            if not isinstance(value, (int, float)) or not value >= 0.0 or value == float("inf"):
                raise ValueError(f"{name} must be a finite number >= 0, got {value!r}")

    def tolerances(self, n: int) -> Tolerances:
        return self.defaults if self.defaults is not None else Tolerances.defaults(n)

    def timeout(self) -> float:
        """``cmd_timeout`` as JTC applies it: only if it exceeds the default ``goal_time``."""
        goal_time = self.defaults.goal_time if self.defaults is not None else 0.0
        return self.cmd_timeout if self.cmd_timeout > goal_time else 0.0


def prepare_trajectory(settings: GoalSettings, limits: JointLimits | None, joints: Sequence[str], stamp: float,
                       names: Sequence[str], points: Sequence[RawPoint], now: float,
                       state: tuple[FloatArray, FloatArray] | None, effort_sizes: Sequence[int] = ()
                       ) -> tuple[JointTrajectoryReference | None, str]:
    """A trajectory (a goal's or a topic's) received at ``now`` as a reference from the measured
    ``state``, or the one-line reason it is refused: JTC's checks in JTC's order
    (:func:`~.joint_trajectory.check_trajectory`), then -- beyond JTC -- its values finite and,
    with ``limits`` and ``settings.reject_beyond_limits``, the arm's limits and no step.
    ``joints``: the controlled joints in robot order."""
    names = tuple(names)
    problem = check_trajectory(settings.rules, joints, stamp, names, points, now, effort_sizes)
    if problem:
        return None, problem
    if state is None:
        return None, "no complete joint state yet (the motion starts from it)"
    reference, problem = JointTrajectoryReference.from_checked(joints, stamp, names, points, now, *state,
                                                               wrap=settings.wrap)
    if reference is None:
        return None, problem
    if limits is not None and settings.reject_beyond_limits:
        problem = limits.trajectory_problem(reference, settings.start_tolerance)
        if problem:
            return None, f"beyond the arm's limits (reject_beyond_limits): {problem}"
    return reference, ""


@dataclass
class Feedback:
    """The latest control period of a goal (robot order): its time, desired, actual and error."""

    time: float
    desired: tuple[FloatArray, FloatArray, FloatArray]
    actual: tuple[FloatArray, FloatArray]
    error: tuple[FloatArray, FloatArray]


def wrapped(error: FloatArray, wrap: FloatArray | None) -> FloatArray:
    """``error`` with the entries of continuous joints wrapped to (-pi, pi] (shortest angular distance)."""
    if wrap is None or not wrap.any():
        return error
    return np.where(wrap, np.remainder(error + np.pi, 2.0 * np.pi) - np.pi, error)


@dataclass
class GoalExecution:
    """One running trajectory, checked every control period by :meth:`update` (the control loop):
    an action goal's (watched by the action server's thread: :attr:`done`, :attr:`outcome`,
    :attr:`feedback`) or a topic trajectory's (``action`` False: it never succeeds, it only
    ends by a hold).

    Parameters
    ----------
    reference : JointTrajectoryReference
        The trajectory on the controller's clock (a topic trajectory replaces it).
    tolerances : Tolerances
        Resolved per joint (robot order).
    names : tuple of str
        The joints in robot order (for the reasons given).
    action : bool
        An action goal (it succeeds) or a topic trajectory.
    cmd_timeout : float
        Hold this long after the last point (s; 0: never).
    wrap : ndarray of bool, optional
        Continuous joints.
    """

    reference: JointTrajectoryReference
    tolerances: Tolerances
    names: tuple[str, ...]
    action: bool = True
    cmd_timeout: float = 0.0
    wrap: FloatArray | None = None
    outcome: Outcome | None = None
    feedback: Feedback | None = None
    done: threading.Event = field(default_factory=threading.Event)
    first_sample: bool = True

    def __getstate__(self) -> dict[str, object]:
        """Pickled without :attr:`done` (an event of this process): a goal validated in the goal
        process (:mod:`.sidecar.goal_process`) is sent to the control loop's."""
        state = dict(self.__dict__)
        del state["done"]
        return state

    def __setstate__(self, state: dict[str, object]) -> None:
        self.__dict__.update(state)
        self.done = threading.Event()
        if self.outcome is not None:
            self.done.set()

    def follow(self, reference: JointTrajectoryReference) -> None:
        """A topic trajectory replaces the running one; the goal goes on, judged against it."""
        self.reference = reference
        self.first_sample = True

    def update(self, t: float, q: FloatArray, qd: FloatArray,
               desired: tuple[FloatArray, FloatArray, FloatArray]) -> Outcome | None:
        """Check one control period at time ``t``; the outcome once it ends here, else None."""
        if self.outcome is not None:
            return None
        q, qd = np.asarray(q, dtype=float), np.asarray(qd, dtype=float)
        error_q, error_qd = wrapped(desired[0] - q, self.wrap), desired[1] - qd
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
        if joint < 0 and self.action:
            return self.finish(Outcome("succeeded", SUCCESSFUL, "Goal successfully reached!"))
        if joint >= 0 and tol.goal_time != 0.0 and late > tol.goal_time:
            why = _describe(self.names[joint], joint, error_q, error_qd)
            return self.finish(Outcome("aborted", GOAL_TOLERANCE_VIOLATED,
                                       f"Aborted due to goal_time_tolerance exceeding by {late:.6f} seconds: {why}"))
        if self.cmd_timeout > 0.0 and late > self.cmd_timeout:
            # JTC holds and then reports such a goal successful; a goal outside its goal tolerance is
            # not reported reached here
            why = "" if joint < 0 else f": {_describe(self.names[joint], joint, error_q, error_qd)}"
            return self.finish(Outcome("aborted", GOAL_TOLERANCE_VIOLATED,
                                       f"Aborted due to command timeout ({self.cmd_timeout:g} s after the last "
                                       f"point){why}"))
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
    """The controller's running trajectory check (an action goal or a topic trajectory), shared by
    the control loop and the action server's thread.

    The action thread :meth:`start` s and :meth:`cancel` s goals and :meth:`follow` s topic
    trajectories; the loop :meth:`check` s the active one every period. One lock orders them
    (held for a few attribute stores, never while a trajectory is validated), so a hold decided
    by the loop never replaces a goal the action thread has just started, and the reverse.

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

    def goal(self) -> GoalExecution | None:
        """The active action goal, if any."""
        active = self.active
        return active if active is not None and active.action else None

    def start(self, goal: GoalExecution) -> GoalExecution | None:
        """Drive ``goal`` from now on; the action goal it preempted (aborted, INVALID_GOAL), if any."""
        with self.lock:
            old = self.active
            if old is not None and (old.finish(PREEMPTED) is None or not old.action):
                old = None  # it had ended already, or it was a topic trajectory
            self.active = goal
            self._drive(goal.reference)
        return old

    def follow(self, reference: JointTrajectoryReference, tolerances: Tolerances, names: tuple[str, ...],
               cmd_timeout: float, wrap: FloatArray | None = None) -> bool:
        """A topic trajectory drives from now on: the active action goal goes on against it
        (whether there was one), else it is checked against ``tolerances`` (the defaults)."""
        with self.lock:
            active = self.active
            if active is not None and active.action and active.outcome is None:
                active.follow(reference)
                self._drive(reference)
                return True
            self.active = GoalExecution(reference, tolerances, names, action=False, cmd_timeout=cmd_timeout,
                                        wrap=wrap)
            self._drive(reference)
            return False

    def cancel(self, goal: GoalExecution) -> bool:
        """Cancel ``goal`` if it is the active one and hold where the arm is; whether it was."""
        with self.lock:
            if self.active is not goal or goal.finish(CANCELED) is None:
                return False
            self.active = None
            self._hold("goal canceled")
            return True

    def end(self, why: str, code: int = INVALID_GOAL) -> GoalExecution | None:
        """The controller stops (deactivated, stale inputs, a runaway): the active goal, if any, ends
        aborted with ``code`` and ``why`` (returned); a topic trajectory's check ends too."""
        with self.lock:
            old, self.active = self.active, None
            if old is not None and old.finish(Outcome("aborted", code, why)) is not None and old.action:
                return old
            return None

    def check(self, t: float, q: FloatArray, qd: FloatArray,
              desired: tuple[FloatArray, FloatArray, FloatArray]) -> tuple[Outcome | None, bool]:
        """The loop's period at time ``t``: ``(outcome if the active trajectory ended now, whether
        the controller holds from now on)``. A violated one holds the arm where it is (the
        caller recomputes this period's reference); a reached goal holds its last point by
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
