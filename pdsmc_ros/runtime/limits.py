"""The arm's limits in the controller (issue 29 item 2, controller side). ROS-free.

A trajectory or goal that starts from or passes outside the joints' position
limits, or whose velocities exceed their velocity limits, is refused with the
joint, the point and its time named. The torque clamp itself is
:class:`~pdsmc_ros.runtime.commanding.TorqueGuard` (``np.clip(tau, -limit, limit)``,
the same clamp as the in-process simulator's).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from .joint_trajectory import JointTrajectoryReference

FloatArray = np.ndarray
SAMPLES_PER_SEGMENT = 20  # a segment's polynomial is checked at this many instants besides its ends
SLACK = 1e-9  # rad, rad/s: a point exactly on a limit is inside


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

    def trajectory_problem(self, reference: JointTrajectoryReference) -> str:
        """Why ``reference`` leaves the limits (the first violation: joint, point, time), or ""."""
        problem = self.state_problem(reference.start_q)
        if problem:
            return f"it starts from a state outside the joint limits: {problem}"
        for k in range(len(reference.times)):
            # the segment that ends at point k, along its polynomial (a cubic or quintic may
            # overshoot between points) and at the point itself: one vectorised evaluation
            t, q, qd = reference.segment_samples(k, SAMPLES_PER_SEGMENT)
            lo, hi = self.position[:, 0], self.position[:, 1]
            bad = (q < lo - SLACK) | (q > hi + SLACK) | (np.abs(qd) > self.velocity + SLACK)
            if bad.any():
                row = int(np.argmax(bad.any(axis=1)))
                at = "at point" if row == len(t) - 1 else "before point"
                return f"{self._violation(q[row], qd[row])} {at} {k} (t = {t[row]:.3f} s from receipt)"
        return ""

    def _violation(self, q: FloatArray, qd: FloatArray) -> str:
        for i, name in enumerate(self.names):
            lo, hi = self.position[i]
            if not lo - SLACK <= q[i] <= hi + SLACK:
                return f"joint {name!r} position {q[i]:.6g} rad is outside its limits [{lo:g}, {hi:g}]"
            if abs(qd[i]) > self.velocity[i] + SLACK:
                return f"joint {name!r} velocity {qd[i]:.6g} rad/s exceeds its limit {self.velocity[i]:g}"
        return ""
