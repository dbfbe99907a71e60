"""Standard ``trajectory_msgs/JointTrajectory`` references, as joint_trajectory_controller reads them.

The semantics of ros2_controllers' joint_trajectory_controller (Jazzy, 4.x:
``joint_trajectory_controller.cpp`` ``validate_trajectory_msg``, ``fill_partial_goal``;
``trajectory.cpp``, ``interpolate_between_points``):

- validation (:func:`check_trajectory`), in JTC's order: the joint count (unless
  ``allow_partial_joints_goal``), empty ``joint_names``, no points, a joint the controller
  does not have, a non-zero velocity at the last point (unless
  ``allow_nonzero_velocity_at_trajectory_end``), a non-zero ``header.stamp`` whose end lies
  in the past, ``time_from_start`` not strictly increasing, a field whose size is not the
  joint count, an ``effort`` field. Beyond JTC, checked here too: at most
  :attr:`TrajectoryRules.max_points` points (before anything else: validation runs off the
  control loop but must stay short), a joint named twice, a value that is not finite;
- a point's ``time_from_start`` counts from ``header.stamp``; a zero stamp means "on
  receipt"; joints missing from a partial trajectory keep their measured position at
  receipt, with zero velocity and acceleration where the points give those;
- before the first point, the reference moves from the state at receipt to the first
  point; between two points the segment is a quintic polynomial when both points give
  velocities and accelerations, a cubic one when both give velocities, and linear in
  position otherwise; the segment from the state at receipt is cubic at most (a measured
  state has no acceleration, as in the controller without acceleration interfaces);
- after the last point the reference holds the last point's position and velocity (zero
  unless ``allow_nonzero_velocity_at_trajectory_end``), at zero acceleration (JTC repeats
  the last point's acceleration as well; the laws here take the reference acceleration as a
  feed-forward, which must not push a standing reference);
- a new message replaces whatever was left of the previous one (the controller starts it
  from the state at its receipt). ROS-free.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..contours.polynomials import segment
from .joints import JointSelector

FloatArray = np.ndarray

RawPoint = tuple[Sequence[float], Sequence[float], Sequence[float], int, int]
"""A decoded point: positions, velocities, accelerations, ``time_from_start`` (sec, nanosec)."""

FLOAT_EPSILON = float(np.finfo(np.float32).eps)  # JTC compares a "zero" velocity with float's epsilon
MAX_POINTS = 5_000
"""Largest trajectory accepted (points); a larger one is refused with this number in the reason,
before it is looked at (beyond JTC, which has no limit). Validation runs in the action server's
thread, off the control loop, but a client waits for it: ``bench/goal_validation.py`` prints its
cost (with a load average of 21 on this 2-core machine, 5,000 points took 0.19 s with positions
only and 0.89 s with quintic segments). Planners send tens to hundreds of points."""


@dataclass(frozen=True)
class TrajectoryRules:
    """What a trajectory may be (joint_trajectory_controller's parameters of the same names).

    Parameters
    ----------
    allow_partial_joints_goal : bool
        A trajectory may name some of the controlled joints (the others hold their position).
    allow_nonzero_velocity_at_trajectory_end : bool
        The last point may move.
    max_points : int
        The largest trajectory accepted (beyond JTC).
    """

    allow_partial_joints_goal: bool = False
    allow_nonzero_velocity_at_trajectory_end: bool = False
    max_points: int = MAX_POINTS

    def __post_init__(self) -> None:
        if not isinstance(self.max_points, int) or self.max_points < 1:
            raise ValueError(f"max_points must be an integer >= 1, got {self.max_points!r}")


def _seconds(sec: int, nanosec: int) -> float:
    return sec + nanosec * 1e-9


def check_trajectory(rules: TrajectoryRules, joints: Sequence[str], stamp: float, names: Sequence[str],
                     points: Sequence[RawPoint], now: float, effort_sizes: Sequence[int] = ()) -> str:
    """Why a trajectory is refused, in joint_trajectory_controller's order (``validate_trajectory_msg``),
    or "" (see the module docstring). One line naming the field, the point or the joint.

    Parameters
    ----------
    rules : TrajectoryRules
        What is allowed.
    joints : sequence of str
        The controlled joints.
    stamp : float
        ``header.stamp`` (s); 0: on receipt.
    names, points
        ``joint_names`` and the points.
    now : float
        Receipt on the controller's clock (the stamp's clock).
    effort_sizes : sequence of int
        The size of each point's ``effort`` field (empty: none has one).
    """
    if len(points) > rules.max_points:
        return (f"{len(points)} points: the controller validates at most {rules.max_points} points "
                "a trajectory (send a longer motion in pieces)")
    n = len(joints)
    if not rules.allow_partial_joints_goal and len(names) != n:
        missing = [j for j in joints if j not in names]
        detail = f"joint {missing[0]!r} missing" if missing else f"{len(names) - n} more than the controller's"
        return (f"joints on incoming trajectory don't match the controller joints: {len(names)} joint_names for "
                f"{n} joints {list(joints)} ({detail}; allow_partial_joints_goal is false)")
    if not names:
        return "empty joint_names on incoming trajectory"
    if not points:
        return "Empty trajectory received: a trajectory without points"
    for name in names:
        if name not in joints:
            return f"incoming joint {name!r} doesn't match the controller's joints {list(joints)}"
    if not rules.allow_nonzero_velocity_at_trajectory_end:
        last = points[-1][1]
        for i, value in enumerate(last):
            if abs(value) > FLOAT_EPSILON:
                joint = names[i] if i < len(names) else f"#{i}"
                return (f"velocity of the last trajectory point of joint {joint!r} is not zero: {value:.15g} "
                        "(allow_nonzero_velocity_at_trajectory_end is false)")
    if stamp != 0.0:
        end = stamp + _seconds(*points[-1][3:5])
        if end < now:
            return (f"header.stamp {stamp:.9f} s is not zero and the trajectory ends {now - end:.3f} s before it "
                    f"was received (at {end:.9f} s, now {now:.9f} s): a trajectory that ended in the past")
    count = len(names)
    previous = 0.0
    for k, (p, v, a, sec, nanosec) in enumerate(points):
        t = _seconds(sec, nanosec)
        if k and not t > previous:
            return (f"time_from_start of point {k} ({t:.9g} s) is not after point {k - 1}'s ({previous:.9g} s): "
                    "times must strictly increase")
        previous = t
        for field, values, may_be_empty in (("positions", p, False), ("velocities", v, True),
                                            ("accelerations", a, True)):
            if len(values) != count and not (may_be_empty and not len(values)):
                return (f"point {k} has {len(values)} {field} for {count} joint_names "
                        f"(mismatch between joint_names and {field})")
        if k < len(effort_sizes) and effort_sizes[k]:
            return (f"point {k} has an effort field: the control laws compute their own torque and take no "
                    "feed-forward effort (leave effort empty)")
    if len(set(names)) != len(names):  # beyond JTC, which maps a repeated joint onto one of them
        return f"joint_names repeats a joint: {list(names)}"
    return ""


class JointTrajectoryReference:
    """One accepted trajectory: the reference ``(q, qd, qdd)`` at any time.

    Build it with :meth:`from_checked` (or :meth:`from_message`). Times are seconds on the clock
    the controller runs on (its ROS clock in real time, sim time in lockstep).
    """

    def __init__(self, times: FloatArray, positions: Sequence[FloatArray],
                 velocities: Sequence[FloatArray | None], accelerations: Sequence[FloatArray | None],
                 start_time: float, start_q: FloatArray, start_qd: FloatArray) -> None:
        self.times = times  # from receipt, strictly increasing
        self.positions = positions
        self.velocities = velocities
        self.accelerations = accelerations
        self.start_time = start_time  # receipt on the controller's clock: the motion starts there
        self.start_q = start_q
        self.start_qd = start_qd
        self.end_time = start_time + float(times[-1])
        # an action goal stamped 0 starts where the control loop first samples it, not where it
        # was validated (joint_trajectory_controller's Trajectory::sample): :meth:`begin`
        self.starts_at_first_sample = False
        last_v = velocities[-1]
        self._end = (positions[-1], np.zeros_like(positions[-1]) if last_v is None else last_v)

    @classmethod
    def from_checked(cls, joints: Sequence[str], stamp: float, names: Sequence[str], points: Sequence[RawPoint],
                     now: float, q: FloatArray, qd: FloatArray, *, wrap: FloatArray | None = None
                     ) -> tuple[JointTrajectoryReference | None, str]:
        """The reference of a trajectory that passed :func:`check_trajectory`, received at ``now``
        from the measured state ``(q, qd)`` (robot order, as ``joints``): ``(reference, "")``, or
        ``(None, reason)`` for a value that is not finite. Joints the trajectory does not name
        keep ``q`` (``fill_partial_goal``). ``wrap`` (continuous joints): the start of such a
        joint is taken within half a turn of the first point (``wraparound_joint``), so the first
        segment goes the short way round."""
        n = len(joints)
        q = np.asarray(q, dtype=float).copy()
        where = {name: i for i, name in enumerate(joints)}
        index = np.array([where[name] for name in names], dtype=np.intp)
        partial = len(names) != n
        # times relative to receipt: absolute clock readings (1.8e9 s of epoch time) carry only
        # 0.2 us of resolution, which would bend the segments' durations
        start = 0.0 if stamp == 0.0 else stamp - now
        times = np.array([start + _seconds(sec, nanosec) for _, _, _, sec, nanosec in points])
        if not np.all(np.isfinite(times)):
            return None, "time_from_start or header.stamp out of range"
        columns: list[list[FloatArray | None]] = [[], [], []]
        for k, point in enumerate(points):
            for column, (field, values) in enumerate(zip(("positions", "velocities", "accelerations"), point[:3])):
                if column and not len(values):
                    columns[column].append(None)
                    continue
                given = np.asarray(values, dtype=float)
                if not np.all(np.isfinite(given)):
                    bad = int(np.argmin(np.isfinite(given)))
                    return None, f"point {k}: {field} of joint {names[bad]!r} is not finite ({given[bad]})"
                full = (q.copy() if column == 0 else np.zeros(n)) if partial else np.empty(n)
                full[index] = given
                columns[column].append(full)
        positions = [p for p in columns[0] if p is not None]
        start_q = q
        if wrap is not None and wrap.any():
            first = positions[0]
            distance = np.remainder(first - q + np.pi, 2.0 * np.pi) - np.pi
            start_q = np.where(wrap, first - distance, q)
        return cls(times, positions, columns[1], columns[2], now, start_q, np.asarray(qd, dtype=float).copy()), ""

    @classmethod
    def from_message(cls, selector: JointSelector, stamp: float, names: Sequence[str], points: Sequence[RawPoint],
                     now: float, q: FloatArray, qd: FloatArray, rules: TrajectoryRules | None = None
                     ) -> tuple[JointTrajectoryReference | None, str]:
        """:func:`check_trajectory` (JTC's defaults unless ``rules``) then :meth:`from_checked`:
        ``(reference, "")`` or ``(None, reason)``."""
        names = tuple(names)
        problem = check_trajectory(rules or TrajectoryRules(), selector.joints, stamp, names, points, now)
        if problem:
            return None, problem
        return cls.from_checked(selector.joints, stamp, names, points, now, q, qd)

    def __getstate__(self) -> dict[str, object]:
        """Pickled with its points as stacked arrays: a goal validated in another process
        (:mod:`.sidecar.goal_process`) reaches the control loop as a few arrays, not 5,000 small ones
        (unpickled one by one they took milliseconds of the loop's process)."""
        state = dict(self.__dict__)
        for name in ("positions", "velocities", "accelerations"):
            values = state[name]
            if len(values) and not isinstance(values, np.ndarray) and all(v is not None for v in values):
                state[name] = np.stack(values)
            elif not isinstance(values, np.ndarray) and all(v is None for v in values):
                state[name] = (None, len(values))
        return state

    def __setstate__(self, state: dict[str, object]) -> None:
        for name in ("positions", "velocities", "accelerations"):
            values = state[name]
            if isinstance(values, tuple) and len(values) == 2 and values[0] is None:
                state[name] = [None] * int(values[1])
        self.__dict__.update(state)

    def begin(self, t: float) -> None:
        """The control loop is about to sample this trajectory at ``t``: one flagged
        :attr:`starts_at_first_sample` starts there (its times are relative to its start)."""
        if self.starts_at_first_sample:
            self.starts_at_first_sample = False
            self.start_time = t
            self.end_time = t + float(self.times[-1])

    def segment_samples(self, k: int, count: int) -> tuple[FloatArray, FloatArray, FloatArray]:
        """``(t, q, qd)`` at ``count`` instants evenly spread over the segment that ends at point ``k``
        (its end included, its start not): ``t`` (count,) from receipt, ``q`` and ``qd`` (count, n).
        One vectorised evaluation of the segment's polynomial (the limit check of a long goal)."""
        times, v, a = self.times, self.velocities, self.accelerations
        p0: FloatArray
        v0: FloatArray | None
        a0: FloatArray | None
        if k == 0:
            t0 = min(0.0, float(times[0]))
            p0, v0, a0 = self.start_q, self.start_qd, None
        else:
            t0 = float(times[k - 1])
            p0, v0, a0 = self.positions[k - 1], v[k - 1], a[k - 1]
        duration = float(times[k]) - t0
        t = np.linspace(t0, float(times[k]), count + 1)[1:]
        if duration <= 0.0:  # a first point at receipt: no segment leads to it, only the point (a step)
            n = len(p0)
            given = v[k]
            velocity = np.zeros(n) if given is None else given
            return t, np.broadcast_to(self.positions[k], (count, n)), np.broadcast_to(velocity, (count, n))
        # a0 None for k == 0: the segment from the state at receipt is cubic at most (sample())
        q, qd, _ = segment((t - t0)[:, None], duration, p0, v0, a0 if k else None,
                           self.positions[k], v[k], a[k] if k else None)
        return t, np.broadcast_to(q, (count, len(p0))), np.broadcast_to(qd, (count, len(p0)))

    def sample(self, t: float) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Reference ``(q, qd, qdd)`` at time ``t`` (seconds on the controller's clock)."""
        times = self.times
        t = t - self.start_time
        if t >= times[-1]:
            last_q, last_qd = self._end
            return last_q.copy(), last_qd.copy(), np.zeros_like(last_q)
        k = int(np.searchsorted(times, t, side="right"))  # times[k - 1] <= t < times[k]
        v, a = self.velocities, self.accelerations
        if k == 0:
            # from the state at receipt to the first point: cubic where the point gives a
            # velocity (the measured state has none of acceleration), else linear
            t0 = min(0.0, t)
            return segment(t - t0, times[0] - t0, self.start_q, self.start_qd, None,
                           self.positions[0], v[0], None)
        return segment(t - times[k - 1], times[k] - times[k - 1], self.positions[k - 1], v[k - 1],
                       a[k - 1], self.positions[k], v[k], a[k])

    def covers(self, t: float) -> bool:
        """Whether ``t`` lies within the trajectory, from receipt to its last point (``~/query_state``)."""
        return self.start_time <= t < self.end_time
