"""What the stack does when something goes wrong (ROS-free).

* :func:`check_effort` -- an effort command is applied only if it has one
  finite value per actuated joint (the plant checks in lockstep that it is for the current step).
* :func:`safe_torque` -- the plant's safe mode when no effort arrives in time:
  ``damp`` (no drive torque, only braking ``-D qd``) or ``hold`` (stiff hold of
  the configuration where the controller was lost, ``Kp (q_hold - q) - Kd qd``).
* :func:`soft_limit` -- the controller's output limits: ros2_control's soft limits of an effort
  command (velocity bounds from the position limits, effort bounds from the velocity bounds),
  which reduce to per-joint saturation where a joint's limits are unknown.
* :class:`DivergenceCheck` -- a run whose state is not finite or has run away (beyond
  bounds derived from the arm's limits) is stopped; :func:`watch` is its compiled test,
  shared by the in-process loop and the plant node, which also records the first step
  each joint was beyond its position or velocity limit (the plant's warnings).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit
from numpy.typing import NDArray

from ..errors import InvalidInputError
from ..kernel_options import ALLOCATION_FREE
from ..robots.base import FloatArray, Manipulator

SAFE_MODES = ("damp", "hold")
ON_LOSS = ("resume", "end")
# Upper bounds of the safe-mode gains (also the plant parameters' declared ranges): far
# above any useful value, low enough that the safe torque stays finite.
MAX_SAFE_DAMPING = 1.0e6  # N m s/rad
MAX_SAFE_STIFFNESS = 1.0e7  # N m/rad

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


@dataclass(frozen=True)
class SafetyConfig:
    """Plant safe-mode settings.

    Attributes
    ----------
    mode : {"damp", "hold"}
        What the plant applies while the controller is lost.
    damping : float
        Braking gain ``D`` (N m s/rad) of both modes.
    stiffness : float
        ``Kp`` (N m/rad) of ``hold``.
    on_loss : {"resume", "end"}
        Resume control when a controller answers again, or end the run.
    """

    mode: str = "damp"
    damping: float = 5.0
    stiffness: float = 200.0
    on_loss: str = "resume"

    def __post_init__(self) -> None:
        if self.mode not in SAFE_MODES:
            raise InvalidInputError(f"safe_mode must be one of {', '.join(SAFE_MODES)}, got {self.mode!r}")
        if self.on_loss not in ON_LOSS:
            raise InvalidInputError(f"on_controller_loss must be one of {', '.join(ON_LOSS)}, got {self.on_loss!r}")
        for name, most in (("damping", MAX_SAFE_DAMPING), ("stiffness", MAX_SAFE_STIFFNESS)):
            value = getattr(self, name)
            if not np.isfinite(value) or not 0.0 <= value <= most:
                raise InvalidInputError(f"safe_{name} must be a finite number in [0, {most:g}], got {value!r}")


def safe_torque(config: SafetyConfig, q: FloatArray, qd: FloatArray, q_hold: FloatArray) -> FloatArray:
    """Torque of the safe mode (see :class:`SafetyConfig`)."""
    tau = -config.damping * qd
    if config.mode == "hold":
        tau = tau + config.stiffness * (q_hold - q)
    return tau


def check_effort(data: object, n: int) -> tuple[FloatArray | None, str]:
    """``(torque, "")`` if the command may be applied, else ``(None, reason)``.

    One finite value per actuated joint; whether it is for the current step is the
    plant's own check (lockstep only).
    """
    if type(data) is tuple and len(data) == n:
        try:  # the loop's path: the decoder's tuple of floats
            if all(map(math.isfinite, data)):
                return np.array(data, dtype=float), ""
        except (TypeError, OverflowError):
            pass  # judged below
    try:
        tau = np.asarray(data, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        return None, "not numeric"
    if tau.shape != (n,):
        return None, f"wrong length {tau.size} (needs {n})"
    if not np.all(np.isfinite(tau)):
        return None, "non-finite value"
    return tau, ""


# --------------------------------------------------------------------------- #
# Soft limits of an effort command (ros2_control's joint_limits)
# --------------------------------------------------------------------------- #
SOFT_LIMIT_ROWS = 6
"""Rows of a soft-limit table (:func:`soft_limit_table`): effort limit, soft velocity limit, lower
and upper position limit, ``k_position``, ``k_velocity``."""
DEFAULT_K_POSITION = 10.0
"""1/s: the velocity toward a position limit allowed per radian of distance to it (full speed from
``v_max / k_position`` away: 0.3 rad for a 3 rad/s joint)."""
SOFT_VELOCITY_BAND = 0.1
"""The soft velocity limit of a joint is ``(1 - 0.1)`` times its velocity limit, and its default
``k_velocity`` is ``effort_limit / (0.1 velocity_limit)``: the effort that would push the joint
faster than 90 % of its limit shrinks to zero there, and a full braking effort is reached at the
limit itself. ros2_control's rule is a proportional velocity loop: a load that pulls the joint
(gravity, another joint's motion) holds it above its soft velocity limit by ``load / k_velocity``;
with the soft limit at the velocity limit the arm would cruise above it."""


DEADBEAT_SHARE = 0.5
"""The default ``k_velocity`` of a joint is also at most ``0.5 M_ii / h``: half the gain that would
reach the velocity limit in one period (``M_ii``: the joint's smallest inertia, ``h``: the control
period). A sampled loop with a larger gain overshoots the limit by up to ``e_max h / M_ii`` a
period -- several rad/s on a UR5's last wrist joint at 1 kHz -- and oscillates about it."""
INERTIA_SAMPLES = 64
"""Configurations over which :func:`joint_inertia_floor` looks for each joint's smallest inertia."""


def joint_inertia_floor(robot: Manipulator, q: FloatArray) -> FloatArray:
    """Each actuated joint's smallest inertia ``M_ii`` (kg m^2) over ``q`` and
    :data:`INERTIA_SAMPLES` configurations about it (a fixed seed: the same figures every time),
    within the position limits; configurations the arm cannot take (a closed chain that does
    not close) are passed over."""
    q = np.asarray(q, dtype=float)
    limits = np.asarray(robot.position_limits, dtype=float)
    rng = np.random.default_rng(0)
    samples = np.clip(q + rng.uniform(-math.pi, math.pi, (INERTIA_SAMPLES, len(q))), limits[:, 0], limits[:, 1])
    floor = np.full(len(q), np.inf)
    for x in (q, *samples):
        try:
            with np.errstate(all="ignore"):
                diagonal = np.diag(np.asarray(robot.mass_matrix(x), dtype=float))
        except (ValueError, ArithmeticError, np.linalg.LinAlgError):
            continue
        if np.all(np.isfinite(diagonal)) and np.all(diagonal > 0.0):
            floor = np.minimum(floor, diagonal)
    return floor


def soft_limit_table(effort: FloatArray, velocity: FloatArray, position: FloatArray, *,
                     k_position: float = DEFAULT_K_POSITION, k_velocity: FloatArray | None = None,
                     inertia: FloatArray | None = None, period: float | None = None) -> FloatArray:
    """The ``(6, n)`` table :func:`soft_limit` reads, from the arm's limits and the two gains
    (the velocity row: the soft velocity limit, :data:`SOFT_VELOCITY_BAND` below the arm's).

    Parameters
    ----------
    effort, velocity : ndarray, shape (n,)
        Effort (N m) and velocity (rad/s) limits; ``inf`` where unknown.
    position : ndarray, shape (n, 2)
        Lower and upper position limits (rad); ``-inf``/``inf`` where none (continuous joints).
    k_position : float
        ``k_position`` of every joint (1/s), >= 0.
    k_velocity : ndarray, shape (n,), optional
        ``k_velocity`` per joint (N m s/rad), >= 0; by default ``effort / (0.1 velocity)``
        (:data:`SOFT_VELOCITY_BAND`), and at most ``0.5 inertia / period`` (:data:`DEADBEAT_SHARE`)
        where both are given; 0 (no velocity soft limit) where either limit is unknown.
    inertia : ndarray, shape (n,), optional
        Each joint's smallest inertia (:func:`joint_inertia_floor`).
    period : float, optional
        The control period (s).

    Raises
    ------
    InvalidInputError
        A gain negative, not finite or of the wrong length.
    """
    effort = np.asarray(effort, dtype=float).reshape(-1)
    n = effort.shape[0]
    velocity = np.asarray(velocity, dtype=float).reshape(n)
    position = np.asarray(position, dtype=float).reshape(n, 2)
    if not (math.isfinite(k_position) and k_position >= 0.0):
        raise InvalidInputError(f"soft_limits.k_position must be a finite number >= 0 (1/s), got {k_position!r}")
    known = np.isfinite(effort) & np.isfinite(velocity) & (velocity > 0.0)
    if k_velocity is None or len(k_velocity) == 0:
        with np.errstate(divide="ignore", invalid="ignore"):
            kv = np.where(known, effort / (SOFT_VELOCITY_BAND * np.where(known, velocity, 1.0)), 0.0)
        if inertia is not None and period is not None:
            kv = np.minimum(kv, DEADBEAT_SHARE * np.asarray(inertia, dtype=float).reshape(n) / period)
    else:
        kv = np.asarray(k_velocity, dtype=float).reshape(-1)
        if kv.shape != (n,) or not np.all(np.isfinite(kv)) or np.any(kv < 0.0):
            raise InvalidInputError(f"soft_limits.k_velocity must be {n} finite numbers >= 0 (N m s/rad; "
                                    f"empty: effort / ({SOFT_VELOCITY_BAND:g} velocity)), got {kv.tolist()}")
        kv = np.where(known, kv, 0.0)
    table = np.empty((SOFT_LIMIT_ROWS, n))
    table[0] = effort
    table[1] = (1.0 - SOFT_VELOCITY_BAND) * velocity
    table[2] = position[:, 0]
    table[3] = position[:, 1]
    table[4] = k_position
    table[5] = kv
    return table


def robot_soft_limits(robot: Manipulator, q: FloatArray, rate: float, *, k_position: float = DEFAULT_K_POSITION,
                      k_velocity: FloatArray | None = None, effort: FloatArray | None = None) -> FloatArray:
    """The soft-limit table of ``robot``'s actuated joints (its ``effort_limits`` unless
    ``effort`` is given, ``velocity_limits`` and ``position_limits``; :func:`soft_limit_table`)
    for a loop at ``rate`` (Hz) about the configuration ``q``."""
    return soft_limit_table(robot.effort_limits if effort is None else effort, robot.velocity_limits,
                            robot.position_limits, k_position=k_position, k_velocity=k_velocity,
                            inertia=joint_inertia_floor(robot, q), period=1.0 / rate)


def effort_only_table(effort: FloatArray | None, n: int) -> FloatArray:
    """A soft-limit table that only clamps to ``|tau_i| <= effort_i`` (``np.clip``), or clamps
    nothing (``effort`` None)."""
    limit = np.full(n, np.inf) if effort is None else np.asarray(effort, dtype=float).reshape(n)
    return soft_limit_table(limit, np.full(n, np.inf), np.tile([-np.inf, np.inf], (n, 1)))


@njit(**ALLOCATION_FREE)  # type: ignore[untyped-decorator]  # numba's stubs know no runtime option
def soft_limit(tau: FloatArray, q: FloatArray, qd: FloatArray, table: FloatArray, counts: NDArray[np.int64],
               weight: int) -> int:
    """Clamp an effort command between the soft limits of each joint, in place.

    ros2_control's soft limits of an effort interface (``joint_limits``: the rule of ROS 1's
    ``EffortJointSoftLimitsHandle``), per joint ``i``::

        v_lo = clamp(-k_position (q - q_min), -v_max, v_max)    (-v_max without a lower limit)
        v_hi = clamp(-k_position (q - q_max), -v_max, v_max)    ( v_max without an upper limit)
        e_lo = clamp(-k_velocity (qd - v_lo), -e_max, e_max)
        e_hi = clamp(-k_velocity (qd - v_hi), -e_max, e_max)
        tau  = clamp(tau, e_lo, e_hi)

    The effort that would take a joint past its velocity limit, or toward a position limit
    faster than ``k_position`` times its distance, is cut in proportion to the excess (and
    reversed beyond it). A joint with ``k_velocity`` 0 (a limit unknown) is only clamped to
    ``|tau| <= e_max``: with infinite bounds that is ``np.clip`` exactly, float for float.

    Parameters
    ----------
    tau : ndarray, shape (n,)
        The law's torque; limited in place.
    q, qd : ndarray, shape (n,)
        The measured state the torque is for.
    table : ndarray, shape (6, n)
        :func:`soft_limit_table`.
    counts : ndarray of int64, shape (>= n,)
        ``counts[i] += weight`` for each joint ``i`` whose torque ends at its effort limit (the
        saturated periods a run reports, as ``pdsmc analyze`` counts them from a bag's torques).
    weight : int
        What a change adds to ``counts`` (0: a period that is not applied).

    Returns
    -------
    int
        How many joints' torques were changed.
    """
    changed = 0
    for i in range(tau.shape[0]):
        e_max = table[0, i]
        lo = -e_max
        hi = e_max
        kv = table[5, i]
        if kv > 0.0:
            v_max = table[1, i]
            kp = table[4, i]
            v_lo = -v_max
            v_hi = v_max
            if table[2, i] > -np.inf:
                v_lo = min(max(-kp * (q[i] - table[2, i]), -v_max), v_max)
            if table[3, i] < np.inf:
                v_hi = min(max(-kp * (q[i] - table[3, i]), -v_max), v_max)
            lo = min(max(-kv * (qd[i] - v_lo), -e_max), e_max)
            hi = min(max(-kv * (qd[i] - v_hi), -e_max), e_max)
        if tau[i] > hi:
            tau[i] = hi
            changed += 1
        elif tau[i] < lo:
            tau[i] = lo
            changed += 1
        if abs(tau[i]) >= e_max:  # saturated: the statistic a recorded run's torques give too
            counts[i] += weight
    return changed


class Watchdog:
    """The plant's supervision of its controller: when to enter and leave safe mode.

    ROS-free state machine; the plant node feeds it times and events and does the
    stepping, logging and diagnostics. Armed once a controller has answered
    (start-up may take seconds). In lockstep a controller is lost when no effort
    was applied for ``timeout_s`` of wall time; the arm then advances with the
    safe torque at ``time_scale`` x wall-clock pace (:meth:`safe_steps_owed`).
    In real time it is lost after ``periods`` control periods without an effort.

    Parameters
    ----------
    rate : float
        Control rate (Hz).
    timeout_s : float
        Lockstep: wall time without an applied effort that loses the controller.
    periods : int
        Real time: control periods without an effort that lose the controller.
    time_scale : float
        Lockstep safe mode: sim time per wall time (1 real time, 0 frozen).
    """

    def __init__(self, *, rate: float, timeout_s: float, periods: int, time_scale: float) -> None:
        self.rate = rate
        self.timeout_s = timeout_s
        self.periods = periods
        self.time_scale = time_scale
        self.armed = False  # a controller has answered
        self.safe = False
        self.awaiting_resume = False  # lockstep: a controller is back, offered the current state
        self.last_progress = 0.0
        self.periods_without_effort = 0
        self._debt = 0.0  # lockstep safe-mode steps owed to the wall clock
        self._since = 0.0

    def effort(self, now: float) -> bool:
        """An effort was applied at ``now``; whether it ends safe mode."""
        self.armed = True
        self.last_progress = now
        self.periods_without_effort = 0
        if not self.safe:
            return False
        self.safe = self.awaiting_resume = False
        return True

    def lost_in_lockstep(self, now: float) -> bool:
        """Lockstep: whether the controller is lost now (it was not before)."""
        return self.armed and not self.safe and now - self.last_progress > self.timeout_s

    def lost_in_period(self) -> bool:
        """Real time: one period passed; whether the controller is lost now (it was not before)."""
        self.periods_without_effort += 1
        return not self.safe and self.periods_without_effort > self.periods

    def enter(self, now: float) -> None:
        """Safe mode from ``now`` on."""
        self.safe = True
        self.awaiting_resume = False
        self._debt = 0.0
        self._since = now

    def offer_resume(self) -> bool:
        """Lockstep: an effort for another step came in safe mode; whether to offer the
        controller the current state (once: the plant stops stepping alone meanwhile)."""
        if not self.safe or self.awaiting_resume:
            return False
        self.awaiting_resume = True
        return True

    def safe_steps_owed(self, now: float) -> int:
        """Lockstep safe mode: steps to take now to keep ``time_scale`` x wall-clock pace.

        After a stall at most 0.1 s of wall time is caught up at once.
        """
        if not self.safe or self.awaiting_resume:
            return 0
        owed = (now - self._since) * self.time_scale * self.rate
        self._since = now
        self._debt = min(self._debt + owed, 0.1 * self.time_scale * self.rate + 1.0)
        steps = int(self._debt)
        self._debt -= steps
        return steps


class Staleness:
    """The controller's real-time check that its inputs are fresh (ROS-free).

    Inputs older than ``limit_s`` stop the output; fresh ones resume it.
    """

    def __init__(self, limit_s: float) -> None:
        self.limit_s = limit_s
        self.stale = False

    def update(self, now: float, state_time: float, reference_time: float | None) -> str:
        """``"stale"`` or ``"fresh"`` when the inputs just became so, else ``""``.

        ``reference_time`` is None when the reference is computed locally (always fresh).
        """
        stale = now - state_time > self.limit_s or (
            reference_time is not None and now - reference_time > self.limit_s)
        if stale == self.stale:
            return ""
        self.stale = stale
        return "stale" if stale else "fresh"


# --------------------------------------------------------------------------- #
# Joint limits and divergence
# --------------------------------------------------------------------------- #
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
