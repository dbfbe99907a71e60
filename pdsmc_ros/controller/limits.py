"""The arm's limits in the controller (issue 29 item 2, issue 37 item 2, controller side). ROS-free.

A trajectory or goal that starts from or passes outside the joints' position
limits, or whose velocities exceed their velocity limits, is refused with the
joint, the point and its time named -- beyond joint_trajectory_controller, which
starts such a trajectory and aborts it once the arm falls outside the path
tolerance. Its first segment, from the measured state, is checked like every other:
a trajectory whose reference at receipt is not the measured position (a first point
at ``time_from_start`` 0, or a stamp in the past, away from where the arm is) is a
step of unbounded velocity and is refused with the joint, the jump and the time it
needs at the joint's velocity limit, unless the jump is within ``start_tolerance``
(MoveIt starts its trajectories at the current state within its
``allowed_start_tolerance``, 0.01 rad by default). The torque clamp itself is
:class:`~pdsmc_ros.controller.commanding.TorqueGuard` (``np.clip(tau, -limit, limit)``,
the same clamp as the in-process simulator's).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..contours.polynomials import segment
from ..parameters.tables import START_TOLERANCE
from .joint_trajectory import JointTrajectoryReference

FloatArray = np.ndarray
SAMPLES_PER_SEGMENT = 20  # a segment's polynomial is checked at this many instants besides its ends
SLACK = 1e-9  # rad, rad/s: a point exactly on a limit is inside
SEGMENTS_PER_CHUNK = 256  # segments evaluated by one numpy call (short calls: the GIL changes hands between them)


@dataclass(frozen=True)
class JointLimits:
    """Per-joint limits in robot order: ``position`` (n, 2) lower/upper rad, ``velocity`` (n,) rad/s
    (``inf`` where unknown or continuous)."""

    names: tuple[str, ...]
    position: FloatArray
    velocity: FloatArray

    @classmethod
    def of(cls, robot: object, names: Sequence[str]) -> JointLimits:
        """The robot's ``position_limits`` and ``velocity_limits`` (unbounded where it has none)."""
        n = len(names)
        position = getattr(robot, "position_limits", None)
        velocity = getattr(robot, "velocity_limits", None)
        pos = np.tile([-np.inf, np.inf], (n, 1)) if position is None else np.asarray(position, dtype=float)
        vel = np.full(n, np.inf) if velocity is None else np.asarray(velocity, dtype=float)
        return cls(tuple(names), pos.reshape(n, 2), vel.reshape(n))

    def state_problem(self, q: FloatArray) -> str:
        """Why a measured position is outside the limits, or ""."""
        for i, name in enumerate(self.names):
            lo, hi = self.position[i]
            if not lo - SLACK <= q[i] <= hi + SLACK:
                return f"the arm is at joint {name!r} = {q[i]:.6g} rad, outside its limits [{lo:g}, {hi:g}]"
        return ""

    def step_problem(self, reference: JointTrajectoryReference, start_tolerance: float) -> str:
        """Why ``reference`` starts with a step (its position at receipt more than ``start_tolerance``
        from the measured one: the joint, the jump and the time it needs at the velocity limit), or ""."""
        desired = reference.sample(reference.start_time)[0]
        jump = desired - reference.start_q
        far = np.abs(jump) > start_tolerance + SLACK
        if not far.any():
            return ""
        i = int(np.argmax(np.abs(jump) * far))  # the largest jump
        limit = self.velocity[i]
        needs = (f"at its velocity limit {limit:g} rad/s that takes {abs(jump[i]) / limit:.3f} s"
                 if np.isfinite(limit) else "its velocity limit is unknown")
        return (f"a step: joint {self.names[i]!r} would jump {jump[i]:+.4g} rad at once, from the measured "
                f"{reference.start_q[i]:.4g} rad to the trajectory's {desired[i]:.4g} rad at its start; {needs} "
                f"(start the trajectory within {start_tolerance:g} rad of the current position, or give its "
                "first point a later time_from_start)")

    def trajectory_problem(self, reference: JointTrajectoryReference, start_tolerance: float = START_TOLERANCE
                           ) -> str:
        """Why ``reference`` leaves the limits (the first violation: joint, point, time) or starts
        with a step (:meth:`step_problem`), or ""."""
        problem = self.state_problem(reference.start_q)
        if problem:
            return f"it starts from a state outside the joint limits: {problem}"
        problem = self.step_problem(reference, start_tolerance)
        if problem:
            return problem
        # the segment that ends at point k, along its polynomial (a cubic or quintic may overshoot
        # between points) and at the point itself: the first from the state at receipt, the others
        # all at once, a chunk of segments of one kind per evaluation (a 5,000-point goal in a few
        # dozen numpy calls, not 5,000); the first one that leaves the limits is then described
        first_bad = 0 if self._segment_problem(reference, 0) else self._first_bad_segment(reference)
        return "" if first_bad < 0 else self._segment_problem(reference, first_bad)

    def _segment_problem(self, reference: JointTrajectoryReference, k: int) -> str:
        t, q, qd = reference.segment_samples(k, SAMPLES_PER_SEGMENT)
        bad = self._outside(q, qd)
        if not bad.any():
            return ""
        row = int(np.argmax(bad.any(axis=1)))
        at = "at point" if row == len(t) - 1 else "before point"
        return f"{self._violation(q[row], qd[row])} {at} {k} (t = {t[row]:.3f} s from receipt)"

    def _outside(self, q: FloatArray, qd: FloatArray) -> FloatArray:
        lo, hi = self.position[:, 0], self.position[:, 1]
        outside: FloatArray = (q < lo - SLACK) | (q > hi + SLACK) | (np.abs(qd) > self.velocity + SLACK)
        return outside

    def _first_bad_segment(self, reference: JointTrajectoryReference) -> int:
        """The first segment between two points (k >= 1) that leaves the limits, or -1."""
        times, p, v, a = reference.times, reference.positions, reference.velocities, reference.accelerations
        kinds: dict[str, list[int]] = {"linear": [], "cubic": [], "quintic": []}
        for k in range(1, len(times)):
            kind = ("linear" if v[k - 1] is None or v[k] is None
                    else "cubic" if a[k - 1] is None or a[k] is None else "quintic")
            kinds[kind].append(k)
        fractions = np.linspace(0.0, 1.0, SAMPLES_PER_SEGMENT + 1)[1:]
        first = -1
        for kind, ks in kinds.items():
            for start in range(0, len(ks), SEGMENTS_PER_CHUNK):
                index = np.array(ks[start:start + SEGMENTS_PER_CHUNK])
                if first >= 0 and index[0] > first:
                    break
                duration = (times[index] - times[index - 1])[:, None, None]
                t = duration * fractions[None, :, None]
                def column(values: Sequence[FloatArray | None], at: FloatArray) -> FloatArray:  # noqa: E306
                    return np.asarray([values[i] for i in at])[:, None, :]
                p0, p1 = column(p, index - 1), column(p, index)
                v0 = v1 = a0 = a1 = None
                if kind != "linear":
                    v0, v1 = column(v, index - 1), column(v, index)
                if kind == "quintic":
                    a0, a1 = column(a, index - 1), column(a, index)
                q, qd, _ = segment(t, duration, p0, v0, a0, p1, v1, a1)
                q, qd = np.broadcast_arrays(q, qd)
                bad = self._outside(q, qd).any(axis=(1, 2))
                if bad.any():
                    k = int(index[int(np.argmax(bad))])
                    first = k if first < 0 else min(first, k)
                    break
        return first

    def _violation(self, q: FloatArray, qd: FloatArray) -> str:
        for i, name in enumerate(self.names):
            lo, hi = self.position[i]
            if not lo - SLACK <= q[i] <= hi + SLACK:
                return f"joint {name!r} position {q[i]:.6g} rad is outside its limits [{lo:g}, {hi:g}]"
            if abs(qd[i]) > self.velocity[i] + SLACK:
                return f"joint {name!r} velocity {qd[i]:.6g} rad/s exceeds its limit {self.velocity[i]:g}"
        return ""
