"""The plant step: one classical Runge-Kutta step of Eq. (4.1) with the torque held.

The torque is constant over the step (zero-order hold), which is exactly what a
digital controller running at ``1 / h`` applies to the plant. The numpy form
works on any robot (and on batches); the compiled form, the same arithmetic in
the same order, on robots with a compiled form.
"""

from __future__ import annotations

from numba import njit

from ..robots import compiled as robot
from ..robots.base import FloatArray, Manipulator


def rk4_step(
    model: Manipulator, q: FloatArray, qd: FloatArray, tau: FloatArray, h: float
) -> tuple[FloatArray, FloatArray]:
    """Advance Eq. (4.1) by one RK4 step of length ``h`` with ``tau`` held.

    Parameters
    ----------
    model : Manipulator
        The plant model.
    q, qd : ndarray, shape (..., n)
        Joint angles (rad) and rates (rad/s) at the start of the step.
    tau : ndarray, shape (..., n)
        Joint torques (N m) held over the step.
    h : float
        Step length (s).
    """
    f = model._forward_dynamics
    half = 0.5 * h
    a1 = f(q, qd, tau)
    v2 = qd + half * a1
    a2 = f(q + half * qd, v2, tau)
    v3 = qd + half * a2
    a3 = f(q + half * v2, v3, tau)
    v4 = qd + h * a3
    a4 = f(q + h * v3, v4, tau)
    sixth = h / 6.0
    q_next = q + sixth * (qd + 2.0 * v2 + 2.0 * v3 + v4)
    qd_next = qd + sixth * (a1 + 2.0 * a2 + 2.0 * a3 + a4)
    return q_next, qd_next


@njit(cache=True)
def rk4_step_compiled(kind, p, state, tau, h, work):  # noqa: ANN001, ANN201
    """:func:`rk4_step` of a compiled robot ``(kind, p)``: advances ``state`` in place.

    ``state`` starts with ``q`` and ``qd`` (``2 n`` floats; one array: from Python each
    argument of a compiled call costs about 0.1 us).
    """
    n = tau.shape[0]
    q = state[0:n]
    qd = state[n : 2 * n]
    half = 0.5 * h
    v, rest = robot.rows(work, 10, n)
    q_out = v[8]
    qd_out = v[9]
    a1 = v[0]
    a2 = v[1]
    a3 = v[2]
    a4 = v[3]
    v2 = v[4]
    v3 = v[5]
    v4 = v[6]
    x = v[7]
    robot.forward_dynamics(kind, p, q, qd, tau, a1, rest)
    for i in range(n):
        v2[i] = qd[i] + half * a1[i]
        x[i] = q[i] + half * qd[i]
    robot.forward_dynamics(kind, p, x, v2, tau, a2, rest)
    for i in range(n):
        v3[i] = qd[i] + half * a2[i]
        x[i] = q[i] + half * v2[i]
    robot.forward_dynamics(kind, p, x, v3, tau, a3, rest)
    for i in range(n):
        v4[i] = qd[i] + h * a3[i]
        x[i] = q[i] + h * v3[i]
    robot.forward_dynamics(kind, p, x, v4, tau, a4, rest)
    sixth = h / 6.0
    for i in range(n):
        q_out[i] = q[i] + sixth * (qd[i] + 2.0 * v2[i] + 2.0 * v3[i] + v4[i])
        qd_out[i] = qd[i] + sixth * (a1[i] + 2.0 * a2[i] + 2.0 * a3[i] + a4[i])
    for i in range(n):
        q[i] = q_out[i]
        qd[i] = qd_out[i]
