"""Holding a position: the reference a controller commands when it has nothing else.

joint_trajectory_controller holds the position it finds on activation until it
is told otherwise, and the position at the moment of a cancel or an abort
(``set_hold_position``): a reference at that position with zero velocity and
acceleration, driven through whichever law the controller runs (PD, SMC,
PD-SMC: the hold is a reference, not a law of its own). A trajectory that ended
holds its last point by itself (:meth:`JointTrajectoryReference.sample`). With
``constraints.decelerate_on_cancel`` it first brakes each joint at a constant
deceleration (:class:`Stop`, JTC's ``decelerate_to_hold_position``). ROS-free.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

FloatArray = np.ndarray


class Hold:
    """The reference ``(q, 0, 0)`` at every time.

    Parameters
    ----------
    q : sequence of float
        The position to hold (robot order), copied.
    why : str
        What started the hold ("activation", "cancel", "path tolerance violated"...), for logs.
    """

    def __init__(self, q: Sequence[float] | FloatArray, why: str) -> None:
        self.q = np.array(q, dtype=float)
        self.zero = np.zeros_like(self.q)
        self.why = why

    def begin(self, t: float) -> None:  # noqa: ARG002
        """Nothing: a hold has no start time."""

    def sample(self, t: float) -> tuple[FloatArray, FloatArray, FloatArray]:  # noqa: ARG002
        """The held position at zero velocity and acceleration (the same arrays every call:
        the law only reads them)."""
        return self.q, self.zero, self.zero


class Stop:
    """Each joint braked from ``(q, qd)`` at its constant deceleration to rest, then held there:
    joint_trajectory_controller's ``decelerate_to_hold_position`` (``constraints.decelerate_on_cancel``).

    Joint ``i`` stops after ``t_i = |qd_i| / a_i`` at ``q_i + sign(qd_i) qd_i^2 / (2 a_i)``; until
    then its reference is ``q_i + qd_i t - sign(qd_i) a_i t^2 / 2`` at velocity
    ``qd_i - sign(qd_i) a_i t`` and acceleration ``-sign(qd_i) a_i`` (JTC samples the same curve at
    its update period). Time counts from the loop's first sample of it.

    Parameters
    ----------
    q, qd : sequence of float
        The state braking starts from (robot order), copied.
    deceleration : sequence of float
        Each joint's deceleration (rad/s^2, > 0; ``constraints.<joint>.max_deceleration_on_cancel``).
    why : str
        What started the stop, for logs.
    """

    def __init__(self, q: Sequence[float] | FloatArray, qd: Sequence[float] | FloatArray,
                 deceleration: Sequence[float] | FloatArray, why: str) -> None:
        self.q0 = np.array(q, dtype=float)
        self.qd0 = np.array(qd, dtype=float)
        self.a = np.array(deceleration, dtype=float)
        if self.a.shape != self.q0.shape or self.qd0.shape != self.q0.shape or not np.all(self.a > 0.0):
            raise ValueError(f"a stop needs one deceleration > 0 per joint, got {list(self.a)}")
        self.direction = np.where(self.qd0 >= 0.0, 1.0, -1.0)
        self.stop_time = np.abs(self.qd0) / self.a
        self.q = self.q0 + self.direction * self.qd0 ** 2 / (2.0 * self.a)  # where it holds
        self.zero = np.zeros_like(self.q0)
        self.start: float | None = None
        self.why = why

    def begin(self, t: float) -> None:
        """The loop samples it at ``t`` next: the first time, braking starts there."""
        if self.start is None:
            self.start = t

    def sample(self, t: float) -> tuple[FloatArray, FloatArray, FloatArray]:
        """The braking reference at time ``t`` (the held position once every joint stopped)."""
        tau = max(0.0, t - (t if self.start is None else self.start))
        braking = tau < self.stop_time
        if not np.any(braking):
            return self.q, self.zero, self.zero
        decel = self.direction * self.a
        position = np.where(braking, self.q0 + self.qd0 * tau - 0.5 * decel * tau * tau, self.q)
        velocity = np.where(braking, self.qd0 - decel * tau, 0.0)
        velocity = np.where(velocity * self.direction < 0.0, 0.0, velocity)
        return position, velocity, np.where(braking, -decel, 0.0)
