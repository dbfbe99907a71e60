"""What the controller node calls, without ROS: its inputs, references, goals and torque.

The node (:mod:`pdsmc_ros.controller.node`) subscribes, logs and publishes; everything it
decides is here: which state meets which reference (lockstep:
:class:`~.commanding.LockstepPairing`; real time: :class:`~.commanding.LatestInputs`),
where a hold holds (:class:`~.hold.Hold`), where a ``~/joint_trajectory`` starts, whether an
action goal is valid and with which tolerances (:mod:`.goals`), and the torque of the running
law (:class:`~pdsmc_ros.control.ControlLaw`, its formulas in :mod:`pdsmc_ros.control`), the
active goal checked against its tolerances first; each of these steps is run once at configure
(:func:`warm_up`), so none is first run on a real tick. ROS-free.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from typing import Any, NamedTuple, cast

import numpy as np

from ..control.law import ControlLaw
from ..parameters.joint_map import JointMap
from ..robots.base import FloatArray
from ..runs.builder import RunSpec, control_steps
from .commanding import LatestInputs, LockstepPairing, Paired, Reference, RunawayGuard, TorqueGuard
from .goals import (
    INVALID_GOAL,
    PATH_TOLERANCE_VIOLATED,
    GoalExecution,
    GoalSettings,
    GoalSlot,
    Outcome,
    Tolerances,
    prepare_trajectory,
    resolve_tolerances,
)
from .hold import Hold, Stop
from .joint_trajectory import JointTrajectoryReference, RawPoint
from .joints import JointSelector
from .limits import JointLimits

CONTINUITY_TOLERANCE = 0.05
"""rad: a hold keeps the commanded position while every joint is this close to it
(:meth:`ControllerCore.start_state`): above any steady-state error of a tuned law, below what an
arm that could not follow is away from its reference."""
SOURCE_SKEW_S = 5.0  # a zero-stamped trajectory starts at its source time if that is at most this old

Tolerance = tuple[str, float, float, float]
"""A goal's ``(joint name, position, velocity, acceleration)`` tolerance entry."""


class GoalStart(NamedTuple):
    """An action goal as validated on arrival: its execution (to start) or its refusal, and what to log."""

    goal: GoalExecution | Outcome
    warning: str  # "" for none (an unknown joint or illegal value in the goal's tolerances)


def latched_refusal(reason: str) -> str:
    """Why no trajectory may start while the runaway stop is latched for ``reason`` ("" for none)."""
    if not reason:
        return ""
    return f"the runaway stop is latched ({reason}): deactivate and activate the controller first"


def check_topic_trajectory(settings: GoalSettings, limits: JointLimits | None, joints: tuple[str, ...],
                           state: tuple[FloatArray, FloatArray] | None, latched: str, lockstep: bool, stamp: float,
                           names: Sequence[str], points: Sequence[RawPoint], effort_sizes: Sequence[int],
                           times: tuple[float | None, float | None], now: float
                           ) -> tuple[JointTrajectoryReference | None, str]:
    """A ``~/joint_trajectory`` (its stamp, joint names, points and the sizes of their effort
    fields) at controller time ``now``, from the measured ``state``: ``(reference, "")``, or
    ``(None, problem)`` (``latched``: why no trajectory may start, "" for none). Validated as an
    action goal (:func:`~.goals.prepare_trajectory`), in the caller's thread -- or process.

    Real time: a zero ``header.stamp`` starts when the message was sent (``times``: the
    middleware's source and reception times; the reception time if the source time is
    implausible, e.g. another machine's clock off by more than :data:`SOURCE_SKEW_S`), so no
    wait -- the controller still starting, DDS repairing a sample its reader dropped before it
    knew the writer -- shifts the trajectory."""
    if not lockstep:
        sent, received = times
        if sent is not None and now - SOURCE_SKEW_S <= sent <= now:
            now = sent
        elif received is not None and received <= now:
            now = received
    if latched:
        return None, latched
    return prepare_trajectory(settings, limits, joints, stamp, names, points, now, state, effort_sizes)


def check_goal(settings: GoalSettings, limits: JointLimits | None, joints: tuple[str, ...],
               state: tuple[FloatArray, FloatArray] | None, latched: str, stamp: float, names: Sequence[str],
               points: Sequence[RawPoint], effort_sizes: Sequence[int], now: float, path: Sequence[Tolerance],
               goal: Sequence[Tolerance], goal_time: float) -> GoalStart:
    """An action goal (its trajectory's stamp, joint names, points and effort sizes; its path and
    goal tolerances and goal time tolerance) arriving at controller time ``now``, from the
    measured ``state``, validated in the caller's thread (the action server's) or process: its
    execution, with its tolerances over the defaults, to start once accepted, or the refusal
    (INVALID_GOAL and the reason; ``latched``: why no trajectory may start, "" for none)."""
    if latched:
        return GoalStart(Outcome("aborted", INVALID_GOAL, latched), "")
    reference, problem = prepare_trajectory(settings, limits, joints, stamp, names, points, now, state, effort_sizes)
    if reference is None:
        return GoalStart(Outcome("aborted", INVALID_GOAL, problem), "")
    reference.starts_at_first_sample = stamp == 0.0  # JTC: "now" is the loop's first sample of it
    tolerances, warning = resolve_tolerances(settings.tolerances(len(joints)), joints, path, goal, goal_time)
    return GoalStart(GoalExecution(reference, tolerances, tuple(joints), cmd_timeout=settings.timeout(),
                                   wrap=settings.wrap), warning)


def warm_up(law: ControlLaw, selector: JointSelector, limits: JointLimits | None, q: np.ndarray,
            guard: TorqueGuard, joint_map: JointMap) -> None:
    """Run once, on made-up inputs at position ``q``, every step of the path from a message to
    a command: a quintic three-point trajectory parsed and sampled, its limit check, a goal's
    tolerance check, a hold and a braking stop, the law, the torque guard and the joint order of the output; the
    results are discarded.

    A real-time controller must not stall on its first command: numba loads a compiled law on
    its first call, and numpy's first use of a function (searchsorted, polynomial segments, the
    limit check's broadcasting) costs more than later ones (:meth:`ControllerCore.configure`
    calls this)."""
    q = np.asarray(q, dtype=float)
    n = len(q)
    zeros = [0.0] * n
    points = [(list(q + 0.01 * k), zeros, zeros, k, 0) for k in (1, 2, 3)]
    reference, _ = JointTrajectoryReference.from_message(selector, 0.0, selector.joints, points, 0.0,
                                                         q, np.zeros(n))
    if reference is None:  # pragma: no cover - the made-up trajectory is valid
        return
    if limits is not None:
        limits.trajectory_problem(reference)
    goal = GoalExecution(reference, Tolerances.defaults(n), selector.joints)
    for t in (0.5, 1.5, 2.5, 3.5):
        desired = reference.sample(t)
        goal.update(t, q, np.zeros(n), desired)
        tau = law.torque(q, np.zeros(n), *desired)
    tau = law.torque(q, np.zeros(n), *Hold(q, "warm-up").sample(0.0))
    braking = Stop(q, np.full(n, 0.1), np.ones(n), "warm-up")  # a cancel's stop with decelerate_on_cancel
    braking.begin(0.0)
    tau = law.torque(q, np.zeros(n), *braking.sample(0.05))
    # a torque inside the limits: the guard's counters stay at zero
    zero = np.zeros_like(tau)
    guard.limit(zero, q, np.zeros(n))
    guard.check(joint_map.to_user(zero))


class ControllerCore:
    """The controller node's decisions about one run (gains in robot order).

    Parameters
    ----------
    spec : RunSpec
        The run, with the gains in robot order (replaced by :meth:`apply_gains`).
    selector : JointSelector
        Messages by joint name, into robot order.
    joint_map : JointMap
        ``joints`` order <-> robot order (the warm-up's output order).
    limits : JointLimits or None
        The trajectory limit check; None: ``enforce_limits:=false``.
    guard : TorqueGuard
        The arm's soft limits and the last check of a torque (warmed up at :meth:`configure`).
    stale_s : float
        Real time: inputs older than this stop the output.
    lockstep : bool
        Lockstep (states paired with references by step) or real time (the latest inputs).
    on_hold : callable
        ``on_hold(why)``: told of every hold that took effect (the node logs it).
    runaway : RunawayGuard, optional
        The runaway stop (None: none, ``enforce_limits:=false``).
    on_runaway : callable
        ``on_runaway(why)``: told when the runaway guard trips (the node reports it).
    goal_settings : GoalSettings, optional
        How trajectories and goals are taken (JTC's parameters and the project's checks).
    """

    def __init__(self, spec: RunSpec, selector: JointSelector, joint_map: JointMap, limits: JointLimits | None,
                 guard: TorqueGuard, stale_s: float, lockstep: bool, on_hold: Callable[[str], None], *,
                 runaway: RunawayGuard | None = None, on_runaway: Callable[[str], None] = lambda why: None,
                 goal_settings: GoalSettings | None = None) -> None:
        self.spec = spec
        self.selector, self.joint_map, self.limits, self.guard = selector, joint_map, limits, guard
        self.lockstep = lockstep
        self.on_hold = on_hold
        self.runaway = runaway
        self.on_runaway = on_runaway
        self.goal_settings = goal_settings or GoalSettings()
        self.limit_note = ""  # the soft limits' latest line to log ("" for none)
        self.reference = spec.reference()
        self.pairing = LockstepPairing(spec.rate, control_steps(spec.contour_model().duration, spec.rate))
        self.latest = LatestInputs(stale_s)
        self.goals = GoalSlot(self.pairing.drive if lockstep else self.latest.drive,  # type: ignore[arg-type]
                              self.hold)
        self.law: ControlLaw | None = None  # None until configured
        self.states_received = 0
        self.last_state: tuple[int, FloatArray, FloatArray] | None = None  # where a trajectory goal starts
        self.snapshot: tuple[Any, ...] | None = None  # the latest period's (t, q, qd, reference, torque), robot order
        self.commanded: tuple[FloatArray, FloatArray] | None = None  # the latest reference's position and velocity

    # -- lifecycle ------------------------------------------------------------ #
    def configure(self) -> None:
        """Everything a first state, trajectory or goal needs, loaded and run once now (numba
        loads the law's kernel on its first call): never on the first tick."""
        start = self.reference.sample([0.0])
        self.law = ControlLaw.from_spec(self.spec).warm_up(start.q[0], start.qd[0])
        warm_up(self.law, self.selector, self.limits, start.q[0], self.guard, self.joint_map)

    def activate(self) -> None:
        """Real time: hold the first state that comes from now on; a stateful law's integrator
        starts from zero."""
        self.latest.activate()
        if self.runaway is not None:
            self.runaway.reset()
        if self.law is not None:
            self.law.reset()

    def apply_gains(self, spec: RunSpec) -> None:
        """The run with new gains (already checked stable); a stateful law keeps integrating."""
        self.spec = spec
        if self.law is not None:
            self.law = self.law.with_gains(spec.gains.matrix())  # one attribute store: a period uses the old or the new

    def start_state(self) -> tuple[FloatArray, FloatArray] | None:
        """Where a hold starts: the position and velocity the controller commands now while every
        joint is within :data:`CONTINUITY_TOLERANCE` of it, else the measured state (None before
        the first state).

        joint_trajectory_controller holds the measured position; an effort controller whose law
        leaves a steady-state error (PD under gravity) would then sink by that error at every
        cancel (200 send-and-cancel pairs left a UR5's elbow 0.15 rad lower). Holding the
        commanded position keeps the error from accumulating; an arm that is far from it (it
        could not follow, it was pushed) is held where it is. A new trajectory starts from the
        measured state, as JTC's (a client such as MoveIt starts it at the position it measures,
        and its step check compares with that)."""
        if self.last_state is None:
            return None
        q, qd = self.last_state[1], self.last_state[2]
        commanded = self.commanded
        if commanded is not None and np.all(np.abs(commanded[0] - q) <= CONTINUITY_TOLERANCE):
            return commanded
        return q, qd

    def hold(self, why: str, *, measured: bool = False) -> None:
        """Hold from now on (a cancel, an abort): the commanded position while the arm is close to
        it (:meth:`start_state`), else -- or with ``measured`` -- the measured position. With
        ``constraints.decelerate_on_cancel`` a cancel or an abort first brakes from that state's
        velocity (:class:`~pdsmc_ros.controller.hold.Stop`; JTC brakes from the measured state,
        this from the state the hold would keep, for the same reason)."""
        start = None if measured else self.start_state()
        decelerations = self.goal_settings.stop_deceleration
        if decelerations is not None and start is not None:
            drive = self.pairing.drive if self.lockstep else self.latest.drive
            drive(Stop(start[0], start[1], decelerations, why))
        elif self.lockstep:
            if self.last_state is None:
                return
            self.pairing.drive(Hold(self.last_state[1] if start is None else start[0], why))
        elif not self.latest.hold(why, None if start is None else start[0]):
            return
        self.on_hold(why)

    def sim_time(self) -> float:
        """Lockstep: the controller's time (s), the latest state's step."""
        return (0 if self.last_state is None else self.last_state[0]) / self.spec.rate

    # -- inputs --------------------------------------------------------------- #
    def add_state(self, data: bytes, topic: str) -> tuple[Paired | None, str | None]:
        """A serialized ``JointState`` on ``topic``: ``(the pair it completes (lockstep), None)``,
        or ``(None, a problem naming topic)``."""
        sec, nanosec, arrays, problem = self.selector.state_message(data, topic)
        if arrays is None:
            self.latest.state = None  # real time: no torque from an older state meanwhile
            return None, problem
        step = self.pairing.step_of(sec, nanosec) if self.lockstep else -1  # real time: never a step
        if step is None:
            return None, (f"/{topic} stamp {sec}.{nanosec:09d} s is not a lockstep step "
                          "(lockstep needs the plant's sim time; use mode:=realtime)")
        self.states_received += 1
        q, qd = cast(tuple[FloatArray, FloatArray], arrays)  # the selector's arrays
        self.last_state = (step, q, qd)
        if self.lockstep:
            return self.pairing.add_state(step, q, qd), None
        self.latest.add_state(q, qd, time.perf_counter())
        return None, None

    def add_reference(self, data: bytes, topic: str) -> tuple[Paired | None, str]:
        """A serialized one-point ``JointTrajectory`` on ``topic`` (the reference stream):
        ``(the pair it completes (lockstep), "")``, or ``(None, a problem naming topic)``."""
        sec, nanosec, ref, problem = self.selector.reference_message(data, topic)
        if ref is None:
            return None, problem
        if not self.lockstep:
            self.latest.add_reference(ref, time.perf_counter())  # type: ignore[arg-type]
        elif (step := self.pairing.step_of(sec, nanosec)) is not None:
            return self.pairing.add_reference(step, ref), ""  # type: ignore[arg-type]
        return None, ""

    def topic_trajectory(self, stamp: float, names: Sequence[str], points: Sequence[RawPoint],
                         effort_sizes: Sequence[int], times: tuple[float | None, float | None], now: float
                         ) -> tuple[JointTrajectoryReference | None, str, bool]:
        """A ``~/joint_trajectory`` (its stamp, joint names, points and the sizes of their effort
        fields) at controller time ``now``: ``(reference, "", whether an action goal goes on
        against it)`` once it drives, or ``(None, problem, False)`` (the running motion untouched):
        :meth:`check_topic_trajectory`, then :meth:`follow`."""
        reference, problem = self.check_topic_trajectory(stamp, names, points, effort_sizes, times, now)
        if reference is None:
            return None, problem, False
        return reference, "", self.follow(reference)

    def check_topic_trajectory(self, stamp: float, names: Sequence[str], points: Sequence[RawPoint],
                               effort_sizes: Sequence[int], times: tuple[float | None, float | None], now: float
                               ) -> tuple[JointTrajectoryReference | None, str]:
        """A ``~/joint_trajectory`` validated from the latest measured state (:func:`check_topic_trajectory`)."""
        return check_topic_trajectory(self.goal_settings, self.limits, self.selector.joints, self.measured(),
                                      self.runaway_latched(), self.lockstep, stamp, names, points, effort_sizes,
                                      times, now)

    def follow(self, reference: JointTrajectoryReference) -> bool:
        """A validated topic trajectory drives from now on; whether an action goal goes on against it."""
        settings, joints = self.goal_settings, self.selector.joints
        return self.goals.follow(reference, settings.tolerances(len(joints)), joints, settings.timeout(),
                                 settings.wrap)

    def check_goal(self, stamp: float, names: Sequence[str], points: Sequence[RawPoint], effort_sizes: Sequence[int],
                   now: float, path: Sequence[Tolerance], goal: Sequence[Tolerance], goal_time: float) -> GoalStart:
        """An action goal validated from the latest measured state (:func:`check_goal`)."""
        return check_goal(self.goal_settings, self.limits, self.selector.joints, self.measured(),
                          self.runaway_latched(), stamp, names, points, effort_sizes, now, path, goal, goal_time)

    def measured(self) -> tuple[FloatArray, FloatArray] | None:
        """The latest complete measured state ``(q, qd)`` (robot order), None before the first:
        where a trajectory starts (joint_trajectory_controller: from the measured state)."""
        return self.last_state[1:] if self.last_state is not None else None

    def runaway_latched(self) -> str:
        """Why no trajectory may start (the runaway stop is latched), or ""."""
        return latched_refusal(self.runaway.reason if self.runaway is not None else "")

    def start_goal(self, execution: GoalExecution) -> bool:
        """Drive an accepted goal from now on; whether it preempted another action goal."""
        return self.goals.start(execution) is not None

    # -- torque --------------------------------------------------------------- #
    def command(self, t: float, q: FloatArray, qd: FloatArray, ref: Reference) -> FloatArray | None:
        """The law's torque for the state ``(q, qd)`` and the reference ``ref`` at time ``t``
        (None before :meth:`configure`), within the arm's soft limits
        (:meth:`TorqueGuard.limit`; a line to log in :attr:`limit_note`), kept with them as
        :attr:`snapshot`. The active goal is checked first: violated, the arm is held where it
        is from this period on. A runaway state (:class:`~.commanding.RunawayGuard`) aborts the
        active goal and commands the guard's stop from then on, whatever drives."""
        law = self.law  # one read: a gain change swaps it from another thread
        if law is None:
            return None
        self.limit_note = ""
        if self.goals.active is not None and self.goals.check(t, q, qd, ref)[1]:
            driving = self.pairing if self.lockstep else self.latest
            ref = driving.trajectory.sample(t)  # type: ignore[union-attr]  # aborted: the hold
        runaway = self.runaway
        if runaway is not None:
            if why := runaway.trip(q, qd, t):
                self.goals.end(why, PATH_TOLERANCE_VIOLATED)
                self.on_runaway(why)
            if runaway.reason:  # latched: the stop's torque, whatever drives
                tau = runaway.torque(qd)
                self.snapshot = (t, q, qd, ref, tau)
                return tau
        self.commanded = (ref[0], ref[1])
        tau = law.torque(q, qd, *ref)
        self.limit_note = self.guard.limit(tau, q, qd)
        self.snapshot = (t, q, qd, ref, tau)
        return tau

    def realtime_command(self, now: float, clock: Callable[[], float]) -> tuple[FloatArray | None, str]:
        """Real time: the torque from the latest inputs at ``now`` (``perf_counter``; None:
        nothing to command), a trajectory sampled at ``clock()``, and ``"stale"`` / ``"fresh"``
        when the inputs just became so (:meth:`~.commanding.LatestInputs.take`)."""
        if self.law is None:
            return None, ""
        inputs, change = self.latest.take(now, clock)
        if change == "stale":  # the output stops: a goal cannot go on
            self.goals.end("inputs stale: the controller stopped commanding")
        elif change == "fresh":  # after an outage the arm is where it is now, not where the trajectory went
            self.commanded = None
            # a goal started during the outage: the hold replaces its trajectory, so it cannot go on (left
            # active, it would be SUCCEEDED at its end time with the arm never having followed it)
            self.goals.end("inputs stale: the controller stopped commanding")
            self.hold("inputs fresh again after an outage", measured=True)
            inputs, _ = self.latest.take(now, clock)
        if inputs is None:
            return None, change
        q, qd, ref, t = inputs
        return self.command(t, q, qd, ref), change
