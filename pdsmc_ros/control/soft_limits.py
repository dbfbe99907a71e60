"""Soft limits of an effort command (ROS-free, compiled): the controller's output limits.

:func:`soft_limit` is ros2_control's soft-limit rule of an effort command (velocity bounds from
the position limits, effort bounds from the velocity bounds), which reduces to per-joint
saturation where a joint's limits are unknown; the controller node and the compiled loop
(:mod:`pdsmc_ros.sim.loop`) apply it alike. Its table comes from the arm's limits
(:func:`robot_soft_limits`) or from effort limits alone (:func:`effort_only_table`).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import NDArray

from ..errors import InvalidInputError
from ..kernels.options import ALLOCATION_FREE
from ..robots.base import FloatArray, Manipulator

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
