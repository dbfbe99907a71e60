"""A run that has diverged is stopped (ROS-free): the simulation's divergence test.

:class:`DivergenceCheck` -- a run whose state is not finite or has run away (beyond bounds
derived from the arm's limits) is stopped; :func:`watch` is its compiled test, shared by the
in-process loop and the plant node, which also records the first step each joint was beyond
its position or velocity limit (the plant's warnings).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import NDArray

from ..errors import InvalidInputError
from ..kernels.options import ALLOCATION_FREE
from ..robots.base import FloatArray, Manipulator

# Divergence bounds (DivergenceCheck): a state this far beyond the arm's limits is no longer
# a tracking error but a loop that has run away (no physical arm gets there)
RUNAWAY_VELOCITY_FACTOR = 10.0
"""A joint rate beyond this many times its velocity limit has run away."""
RUNAWAY_VELOCITY_UNKNOWN = 1.0e3
"""rad/s (or m/s): the runaway rate of a joint whose velocity limit is unknown (about 10,000 rpm)."""
RUNAWAY_POSITION_MARGIN = 2.0 * math.pi
"""rad (or m): a joint a whole turn beyond a finite position limit has run away (no stop holds it)."""
RUNAWAY_TORQUE_FACTOR = 100.0
"""A recorded torque beyond this many times a finite effort limit has run away (a run with the clamp
opted out; no drive delivers it)."""



BOUND_ROWS = 7
"""Rows of :attr:`DivergenceCheck.bounds`: position limits (lower, upper), velocity limit,
runaway bounds (lower, upper position, rate), and the smaller of the velocity limit and the
runaway rate (the common case's test)."""


@njit(**ALLOCATION_FREE)  # type: ignore[untyped-decorator]  # numba's stubs know no runtime option
def watch(q: FloatArray, qd: FloatArray, step: int, bounds: FloatArray, first: NDArray[np.int64],
          at: FloatArray) -> int:
    """Check one state: whether it diverged, and record the first limit crossing of each joint.

    Parameters
    ----------
    q, qd : ndarray, shape (n,)
        Joint angles and rates.
    step : int
        The state's control step.
    bounds : ndarray, shape (7, n)
        :attr:`DivergenceCheck.bounds`.
    first : ndarray of int64, shape (2, n)
        First step each joint was beyond its position (row 0) or velocity (row 1) limit, -1 if
        never; updated in place.
    at : ndarray, shape (4, n)
        The angle (row 0) or rate (row 1) at that step; updated in place (rows 2, 3: the
        diverged state, written by the loop that stops).

    Returns
    -------
    int
        The first joint whose state is not finite or beyond its runaway bound (>= 0); else -2
        if a joint crossed a limit for the first time at this step, else -1.
    """
    n = q.shape[0]
    new = False
    for i in range(n):
        x = q[i]
        v = qd[i]
        # the common case first, in three comparisons: within the position limits and below the
        # smaller of the velocity limit and the runaway rate (finite: NaN and infinities fail it)
        if bounds[0, i] <= x <= bounds[1, i] and abs(v) <= bounds[6, i]:
            continue
        # every comparison with NaN is false, and bounds[5] is finite: NaN and an infinite rate fail
        # here; x - x is 0 for every finite x (an infinite angle beyond an infinite limit fails too)
        if not (bounds[3, i] <= x <= bounds[4, i] and abs(v) <= bounds[5, i] and x - x == 0.0):
            return i
        if not (bounds[0, i] <= x <= bounds[1, i]) and first[0, i] < 0:
            first[0, i] = step
            at[0, i] = x
            new = True
        if abs(v) > bounds[2, i] and first[1, i] < 0:
            first[1, i] = step
            at[1, i] = v
            new = True
    return -2 if new else -1


class DivergenceCheck:
    """When a run has diverged, from the arm's limits; and its position and velocity limit warnings.

    A state has diverged when a joint's angle or rate is not finite, its rate exceeds
    :data:`RUNAWAY_VELOCITY_FACTOR` times its velocity limit (:data:`RUNAWAY_VELOCITY_UNKNOWN`
    where the limit is unknown), or its angle lies more than :data:`RUNAWAY_POSITION_MARGIN`
    beyond a finite position limit. Crossing a limit itself is only a warning (the plant
    reports the first crossing of each joint).

    Parameters
    ----------
    names : sequence of str
        Actuated joints, robot order.
    position_limits : ndarray, shape (n, 2)
        Lower and upper limits (rad; infinite if none).
    velocity_limits : ndarray, shape (n,)
        Largest rates (rad/s; infinite if unknown).
    velocity_factor : float
        A rate beyond this many times the velocity limit has run away (> 0; the controller's
        runaway guard uses a tighter factor than a run's divergence test).
    position_margin : float
        An angle this far (rad, >= 0) beyond a finite position limit has run away.
    """

    def __init__(self, names: tuple[str, ...] | list[str], position_limits: FloatArray,
                 velocity_limits: FloatArray, *, velocity_factor: float = RUNAWAY_VELOCITY_FACTOR,
                 position_margin: float = RUNAWAY_POSITION_MARGIN) -> None:
        if not (math.isfinite(velocity_factor) and velocity_factor > 0.0):
            raise InvalidInputError(f"the runaway velocity factor must be a finite number > 0, got {velocity_factor!r}")
        if not (math.isfinite(position_margin) and position_margin >= 0.0):
            raise InvalidInputError(f"the runaway position margin must be a finite number >= 0 (rad), "
                                    f"got {position_margin!r}")
        n = len(names)
        self.names = tuple(names)
        self.velocity_factor = float(velocity_factor)
        self.position_margin = float(position_margin)
        lower = np.asarray(position_limits, dtype=float)[:, 0]
        upper = np.asarray(position_limits, dtype=float)[:, 1]
        velocity = np.asarray(velocity_limits, dtype=float)
        self.bounds = np.empty((BOUND_ROWS, n))
        """``(7, n)``: lower, upper position limit, velocity limit, runaway lower, upper, rate, and
        ``min(velocity limit, runaway rate)``."""
        self.bounds[0] = lower
        self.bounds[1] = upper
        self.bounds[2] = velocity
        self.bounds[3] = lower - position_margin
        self.bounds[4] = upper + position_margin
        self.bounds[5] = np.where(np.isfinite(velocity), velocity_factor * velocity, RUNAWAY_VELOCITY_UNKNOWN)
        self.bounds[6] = np.minimum(velocity, self.bounds[5])
        self.first: NDArray[np.int64] = np.full((2, n), -1, dtype=np.int64)
        self.at = np.zeros((4, n))
        """Rows 0, 1: the angle and rate of each joint's first limit crossing; rows 2, 3: the
        state a loop stopped at (a diverged run)."""
        self.reported = np.zeros((2, n), dtype=bool)

    @classmethod
    def for_robot(cls, robot: Manipulator) -> DivergenceCheck:
        """The check of ``robot``'s actuated joints (its ``position_limits`` and ``velocity_limits``)."""
        return cls(robot.joint_names, robot.position_limits, robot.velocity_limits)

    def check(self, q: FloatArray, qd: FloatArray, step: int) -> int:
        """:func:`watch` of one state: the diverged joint (>= 0), -2 for a new limit crossing, else -1."""
        return int(watch(q, qd, step, self.bounds, self.first, self.at))

    def diverged(self, joint: int, q: FloatArray, qd: FloatArray, t: float, *, what: str = "diverged") -> str:
        """One line on why the state of ``joint`` counts as diverged (``what``) at time ``t``."""
        name, x, v = self.names[joint], float(q[joint]), float(qd[joint])
        if not (math.isfinite(x) and math.isfinite(v)):
            return f"{what} at t = {t:.6g} s: joint {name!r} state is not finite (position {x:.6g}, rate {v:.6g})"
        if abs(v) > self.bounds[5, joint]:
            limit = self.bounds[2, joint]
            basis = (f"{self.velocity_factor:g} x its velocity limit {limit:.6g} rad/s" if math.isfinite(limit)
                     else f"{RUNAWAY_VELOCITY_UNKNOWN:g} rad/s (its velocity limit is unknown)")
            return f"{what} at t = {t:.6g} s: joint {name!r} rate {v:.6g} rad/s is beyond {basis}"
        return (f"{what} at t = {t:.6g} s: joint {name!r} position {x:.6g} rad is beyond its limits "
                f"[{self.bounds[0, joint]:.6g}, {self.bounds[1, joint]:.6g}] by more than "
                f"{self.position_margin:.4g} rad")

    def new_warnings(self, rate: float) -> list[str]:
        """Lines for the limit crossings recorded since the last call: one per joint and limit
        in a run, naming the joint, the value, the limit and the time (steps at ``rate``)."""
        lines = []
        for kind in (0, 1):
            for i in np.flatnonzero((self.first[kind] >= 0) & ~self.reported[kind]):
                self.reported[kind, i] = True
                lines.append(self.limit_line(kind, int(i), float(self.at[kind, i]), self.first[kind, i] / rate))
        return lines

    def limit_line(self, kind: int, joint: int, value: float, t: float) -> str:
        """``kind`` 0: position, 1: velocity: joint ``joint`` at ``value`` at time ``t``."""
        name = self.names[joint]
        if kind == 0:
            return (f"joint {name!r} position {value:.6g} rad beyond its limits [{self.bounds[0, joint]:.6g}, "
                    f"{self.bounds[1, joint]:.6g}] at t = {t:.6g} s (warned once per joint and run)")
        return (f"joint {name!r} rate {value:.6g} rad/s beyond its velocity limit {self.bounds[2, joint]:.6g} "
                f"rad/s at t = {t:.6g} s (warned once per joint and run)")

    def recorded(self, q: FloatArray, qd: FloatArray, tau: FloatArray, effort_limits: FloatArray,
                 rate: float) -> str:
        """Why a recorded run (rows = control steps at ``rate``; NaN rows: not recorded) counts as
        diverged, or ``""``: an infinite value, a runaway state, or a torque beyond
        :data:`RUNAWAY_TORQUE_FACTOR` times a finite effort limit -- the first such step.
        """
        b = self.bounds
        with np.errstate(invalid="ignore"):
            state = np.isinf(q) | np.isinf(qd) | (q < b[3]) | (q > b[4]) | (np.abs(qd) > b[5])
            torque = np.isinf(tau) | (np.abs(tau) > RUNAWAY_TORQUE_FACTOR * np.asarray(effort_limits, dtype=float))
        bad_state = np.flatnonzero(state.any(axis=1))
        bad_torque = np.flatnonzero(torque.any(axis=1))
        first_state = int(bad_state[0]) if bad_state.size else len(q)
        first_torque = int(bad_torque[0]) if bad_torque.size else len(q)
        if first_state == first_torque == len(q):
            return ""
        if first_state <= first_torque:
            k = first_state
            return self.diverged(int(np.argmax(state[k])), q[k], qd[k], k / rate)
        k = first_torque
        j = int(np.argmax(torque[k]))
        return (f"diverged at t = {k / rate:.6g} s: joint {self.names[j]!r} torque {tau[k, j]:.6g} N m is beyond "
                f"{RUNAWAY_TORQUE_FACTOR:g} x its effort limit {float(effort_limits[j]):.6g} N m")
