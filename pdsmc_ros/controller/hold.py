"""Holding a position: the reference a controller commands when it has nothing else.

joint_trajectory_controller holds the position it finds on activation until it
is told otherwise, and the position at the moment of a cancel or an abort
(``set_hold_position``): a reference at that position with zero velocity and
acceleration, driven through whichever law the controller runs (PD, SMC,
PD-SMC: the hold is a reference, not a law of its own). A trajectory that ended
holds its last point by itself (:meth:`JointTrajectoryReference.sample`). ROS-free.
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
