"""Numerical inverse kinematics of a URDF serial arm, compiled (numba).

Damped least squares on the followed task rows (:mod:`pdsmc_ros.robots.urdf_robot`):
with ``e`` the task error -- position and rotation vector of ``R_d R^T``, both in
the task plane's axes -- and ``J`` the matching rows of the end effector's
Jacobian, a step is ``dq = J^T (J J^T + d^2 I)^-1 e`` (more joints than rows or as
many) or ``(J^T J + d^2 I)^-1 J^T e`` (fewer), with ``d`` zero once the error is
small (Gauss-Newton: quadratic convergence to the tolerance). Steps are clipped to
``max_step`` so a step near a singularity stays local. The robot's kinematics are
:mod:`.spatial_kernels`' (``p`` from :func:`.spatial_layout.pack`).
"""

from __future__ import annotations

from numba import njit

from ..kernels.options import ALLOCATION_FREE
from .kernel_math import rotation_vector, solve_spd
from .spatial_kernels import ee_jacobian, ee_pose
from .spatial_layout import POSE_SIZE, WORK_STRIDE, workspace_size


def scratch_size(n: int) -> int:
    """Floats of scratch :func:`solve_points` needs for ``n`` joints."""
    return workspace_size(n) + 6 * n + 12 + 6 + 6 * n + 36 + 6 + 2 * n + 36


@njit(**ALLOCATION_FREE)
def _damped_gram(x, rows, cols, d2, a):  # noqa: ANN001, ANN202
    """``a[:cols, :cols] = X^T X + d2 I`` with ``X`` the first ``rows`` rows and ``cols`` columns
    of ``x``: the damped normal matrix of a least-squares step (``x`` the task rows of the
    Jacobian, or their transpose)."""
    for i in range(cols):
        for j in range(cols):
            s = d2 if i == j else 0.0
            for r in range(rows):
                s += x[r, i] * x[r, j]
            a[i, j] = s


@njit(**ALLOCATION_FREE)
def solve_points(p, x_d, r_d, seeds, chained, rows, basis, lower, upper, tol, max_iter, damping,  # noqa: ANN001, ANN201, PLR0913
                 undamped_below, max_step, out, ok, work):
    """Solve each target ``(x_d[k], r_d[k])`` into ``out[k]``; ``ok[k]``: converged within limits.

    ``chained``: point ``k`` starts from the solution of ``k - 1`` (the first from
    ``seeds[0]``), and the loop stops at the first failure; otherwise each point
    starts from ``seeds[k]``.
    """
    n = int(p[0])
    m = rows.shape[0]
    base = WORK_STRIDE * n + POSE_SIZE  # spatial_layout.workspace_size(n)
    jac = work[base:base + 6 * n].reshape((6, n))
    at = base + 6 * n
    pos = work[at:at + 3]
    rot = work[at + 3:at + 12].reshape((3, 3))
    at += 12
    err6 = work[at:at + 6]
    at += 6
    jrows = work[at:at + 6 * n].reshape((6, n))
    at += 6 * n
    a = work[at:at + 36].reshape((6, 6))
    at += 36
    y = work[at:at + 6]
    at += 6
    dq = work[at:at + n]
    rhs = work[at + n:at + 2 * n]
    at += 2 * n
    rerr = work[at:at + 9].reshape((3, 3))
    w = work[at + 9:at + 12]
    normal = m > n
    size = n if normal else m
    for k in range(x_d.shape[0]):
        q = out[k]
        if chained and k > 0:
            for i in range(n):
                q[i] = out[k - 1, i]
        else:
            for i in range(n):
                q[i] = seeds[k, i]
        converged = False
        largest_error = 0.0
        for _ in range(max_iter + 1):
            ee_pose(p, q, pos, rot, work)
            ee_jacobian(p, q, jac, work)
            for i in range(3):
                for j in range(3):
                    s = 0.0
                    for c in range(3):
                        s += r_d[k, i, c] * rot[j, c]
                    rerr[i, j] = s
            rotation_vector(rerr, w)
            for i in range(3):
                err6[i] = (basis[i, 0] * (x_d[k, 0] - pos[0]) + basis[i, 1] * (x_d[k, 1] - pos[1])
                           + basis[i, 2] * (x_d[k, 2] - pos[2]))
                err6[3 + i] = basis[i, 0] * w[0] + basis[i, 1] * w[1] + basis[i, 2] * w[2]
            largest_error = 0.0
            for r in range(m):
                largest_error = max(largest_error, abs(err6[rows[r]]))
            if largest_error <= tol:
                converged = True
                break
            for r in range(m):
                row = rows[r]
                block = 0 if row < 3 else 3
                i = row - block
                for c in range(n):
                    jrows[r, c] = (basis[i, 0] * jac[block, c] + basis[i, 1] * jac[block + 1, c]
                                   + basis[i, 2] * jac[block + 2, c])
            d2 = damping * damping if largest_error > undamped_below else 0.0
            if normal:
                _damped_gram(jrows, m, n, d2, a)  # J^T J + d^2 I
                for i in range(n):
                    s = 0.0
                    for r in range(m):
                        s += jrows[r, i] * err6[rows[r]]
                    rhs[i] = s
                if not solve_spd(a, rhs, dq, size):
                    break
            else:
                _damped_gram(jrows.T, n, m, d2, a)  # J J^T + d^2 I
                for i in range(m):
                    rhs[i] = err6[rows[i]]
                if not solve_spd(a, rhs, y, size):
                    break
                for c in range(n):
                    s = 0.0
                    for r in range(m):
                        s += jrows[r, c] * y[r]
                    dq[c] = s
            step = 0.0
            for c in range(n):
                step = max(step, abs(dq[c]))
            scale = max_step / step if step > max_step else 1.0
            for c in range(n):
                q[c] += scale * dq[c]
        within = True
        for c in range(n):
            if q[c] < lower[c] - 1e-9 or q[c] > upper[c] + 1e-9:
                within = False
        ok[k] = (converged or largest_error <= 1e3 * tol) and within
        if chained and not ok[k]:
            return
