"""Warm-up of everything a controller's first state, trajectory or goal runs (issue 25 item 2).

A real-time controller must not stall on its first command: numba loads a
compiled law on its first call, and numpy's first use of a function (searchsorted,
polynomial segments, the limit check's broadcasting) costs more than later ones.
:func:`warm_up` runs each of them once with made-up inputs at configure time,
and discards the results. ROS-free.
"""

from __future__ import annotations

import numpy as np

from ..control.law import ControlLaw
from ..parameters.joint_map import JointMap
from .commanding import TorqueGuard
from .goals import GoalExecution, Tolerances
from .hold import Hold
from .joint_trajectory import JointTrajectoryReference
from .joints import JointSelector
from .limits import JointLimits


def warm_up(law: ControlLaw, selector: JointSelector, limits: JointLimits | None, q: np.ndarray,
            guard: TorqueGuard, joint_map: JointMap) -> None:
    """Run once, on made-up inputs at position ``q``, every step of the path from a message to
    a command: a quintic three-point trajectory parsed and sampled, its limit check, a goal's
    tolerance check, a hold, the law, the torque guard and the joint order of the output."""
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
    # a torque inside the limits: the guard's counters stay at zero
    zero = np.zeros_like(tau)
    guard.limit(zero, q, np.zeros(n))
    guard.check(joint_map.to_user(zero))
