"""Fixed-step integration of the manipulator dynamics (numpy only)."""

from __future__ import annotations

from .models import FloatArray, Manipulator


def rk4_step(
    robot: Manipulator, q: FloatArray, qd: FloatArray, tau: FloatArray, h: float
) -> tuple[FloatArray, FloatArray]:
    """Advance Eq. (4.1) by one classical Runge-Kutta step with ``tau`` held.

    The torque is constant over the step (zero-order hold), which is exactly
    what a digital controller running at ``1 / h`` applies to the plant.

    Parameters
    ----------
    robot : Manipulator
        The plant model.
    q, qd : ndarray, shape (..., n)
        Joint angles (rad) and rates (rad/s) at the start of the step.
    tau : ndarray, shape (..., n)
        Joint torques (N m) held over the step.
    h : float
        Step length (s).
    """
    f = robot._forward_dynamics
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
