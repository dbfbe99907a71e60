"""Standard ``trajectory_msgs/JointTrajectory`` references, as joint_trajectory_controller reads them.

The semantics of ros2_controllers' joint_trajectory_controller topic interface
(``trajectory.cpp``, ``interpolate_between_points``):

- a point's ``time_from_start`` counts from ``header.stamp``; a zero stamp
  means "on receipt";
- before the first point, the reference moves from the state at receipt to
  the first point;
- between two points the segment is a quintic polynomial when both points
  give velocities and accelerations, a cubic one when both give velocities,
  and linear in position otherwise (constant velocity, zero acceleration);
  the segment from the state at receipt is cubic at most (a measured state
  has no acceleration, as in the controller without acceleration interfaces);
- after the last point the reference holds its position at zero velocity
  and acceleration;
- a new message replaces whatever was left of the previous one (the
  controller starts it from the state at its receipt).

Validation follows the controller's: every controlled joint named, each
point's positions one per name, velocities and accelerations empty or one per
name, every value finite, ``time_from_start`` strictly increasing; a trajectory
that ends before it is received is refused. ROS-free.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from ..bag.cdr import decode_joint_trajectory_points
from ..errors import CdrError
from ..trajectories.polynomials import segment
from .joints import JointSelector

FloatArray = np.ndarray

RawPoint = tuple[Sequence[float], Sequence[float], Sequence[float], int, int]
"""A decoded point: positions, velocities, accelerations, ``time_from_start`` (sec, nanosec)."""



class JointTrajectoryReference:
    """One accepted trajectory: the reference ``(q, qd, qdd)`` at any time.

    Build it with :meth:`from_message`. Times are seconds on the clock the
    controller runs on (its ROS clock in real time, sim time in lockstep).
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

    @classmethod
    def from_serialized(cls, selector: JointSelector, data: bytes, now: float,
                        state: tuple[FloatArray, FloatArray] | None) -> tuple[JointTrajectoryReference | None, str]:
        """A serialized ``JointTrajectory`` goal received at ``now`` from the measured ``state``:
        ``(reference, "")`` or ``(None, reason)`` (see :meth:`from_message`)."""
        try:
            sec, nanosec, names, points = decode_joint_trajectory_points(data)
        except CdrError as exc:
            return None, f"malformed message ({exc})"
        if state is None:
            return None, "no complete joint state yet (the motion starts from it)"
        return cls.from_message(selector, sec + nanosec * 1e-9, names, points, now, *state)

    @classmethod
    def from_message(cls, selector: JointSelector, stamp: float, names: tuple[str, ...],
                     points: Sequence[RawPoint], now: float, q: FloatArray, qd: FloatArray
                     ) -> tuple[JointTrajectoryReference | None, str]:
        """Validate a decoded message; ``(reference, "")`` or ``(None, reason)``.

        Parameters
        ----------
        selector : JointSelector
            The controlled joints (the message may name more, in any order).
        stamp : float
            ``header.stamp`` in seconds; 0 means ``now``.
        names : tuple of str
            ``joint_names``.
        points : sequence of RawPoint
            The decoded points.
        now : float
            Receipt time on the controller's clock.
        q, qd : ndarray
            The measured state at receipt, where the motion starts.
        """
        if not points:
            return None, "a trajectory without points"
        if len(set(names)) != len(names):
            return None, f"joint_names repeats a joint: {list(names)}"
        # times relative to receipt: absolute clock readings (1.8e9 s of epoch time) carry only
        # 0.2 us of resolution, which would bend the segments' durations
        start = 0.0 if stamp == 0.0 else stamp - now
        times = np.empty(len(points))
        positions: list[FloatArray] = []
        velocities: list[FloatArray | None] = []
        accelerations: list[FloatArray | None] = []
        for k, (p, v, a, sec, nanosec) in enumerate(points):
            columns = [("positions", p)]
            for field, values in (("velocities", v), ("accelerations", a)):
                if len(values) not in (0, len(names)):
                    return None, f"point {k} has {len(values)} {field} for {len(names)} joint_names"
                if values:
                    columns.append((field, values))
            if len(p) != len(names):
                return None, f"point {k} has {len(p)} positions for {len(names)} joint_names"
            arrays, reason = selector.select(
                names, tuple(field for field, _ in columns), *(values for _, values in columns))
            if reason:
                return None, f"point {k}: {reason}"
            given = dict(zip((field for field, _ in columns), arrays))
            positions.append(given["positions"])
            velocities.append(given.get("velocities"))
            accelerations.append(given.get("accelerations"))
            times[k] = start + sec + nanosec * 1e-9
            if k and not times[k] > times[k - 1]:
                return None, f"time_from_start of point {k} is not after point {k - 1}'s"
        if not math.isfinite(times[-1]):
            return None, "time_from_start or header.stamp out of range"
        if times[-1] < 0.0:
            return None, (f"the trajectory ends {-times[-1]:.3f} s before it was received "
                          "(header.stamp in the past?)")
        return cls(times, positions, velocities, accelerations, now,
                   np.asarray(q, dtype=float).copy(), np.asarray(qd, dtype=float).copy()), ""

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
        if duration <= 0.0:  # a first point at receipt: no segment leads to it, only the point
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
            last = self.positions[-1]
            return last.copy(), np.zeros_like(last), np.zeros_like(last)
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
