"""Rigid-body dynamics of the packed serial chain, compiled (numba): ``Mbar(q)``, ``C qd + G``,
``G``, ``C v`` and Eq. (4.1)'s accelerations -- the chain's entry of :data:`.compiled.COMPILED`.

Algorithms
----------
Featherstone's ("Rigid Body Dynamics Algorithms", 2008) composite-rigid-body
algorithm for ``M(q)`` (ch. 6) and recursive Newton-Euler with zero
acceleration for ``C(q, qd) qd + G(q)`` (ch. 5), written -- unlike Pinocchio,
which works in the joint frames -- with every spatial quantity in base axes and
at the base origin (Featherstone section 5.3's "world coordinates"). In that
frame a joint's motion subspace is ``S = (p x z, z)`` (revolute, axis ``z``
through ``p``) or ``(z, 0)`` (prismatic), velocities add without transforms,
``Sdot = v x S`` and a composite inertia is a plain sum, so the backward passes
are sums and dot products; the one 3x3 rotation per body is its inertia's.
Spatial vectors are Pinocchio's order: linear part first, then angular.
"""

from __future__ import annotations

from numba import njit

from ..kernels.options import ALLOCATION_FREE
from . import spatial_layout as lay
from .kernel_math import solve_spd
from .spatial_kernels import kinematics_pass


@njit(**ALLOCATION_FREE)
def _bias_forces(p, x, gscale, work):  # noqa: ANN001, ANN202
    """RNEA's forward pass with ``qdd = 0``: each body's force ``I a + v x* I v`` into ``work``.

    The base accelerates at ``-gscale * g`` (gravity as a fictitious base
    acceleration, as Pinocchio). Needs :func:`kinematics_pass` at level 2.
    """
    n = int(p[lay.N_JOINTS])
    vx, vy, vz, wx, wy, wz = 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    ax = -gscale * p[lay.GRAVITY]
    ay = -gscale * p[lay.GRAVITY + 1]
    az = -gscale * p[lay.GRAVITY + 2]
    bx, by, bz = 0.0, 0.0, 0.0
    for k in range(n):
        s = k * lay.WORK_STRIDE + lay.W_S
        xk = x[k]
        sx, sy, sz = work[s] * xk, work[s + 1] * xk, work[s + 2] * xk
        tx, ty, tz = work[s + 3] * xk, work[s + 4] * xk, work[s + 5] * xk
        # a_k = a_{k-1} + v_k x S_k x_k = a_{k-1} + v_{k-1} x S_k x_k (Sdot = v x S)
        c0, c1, c2, c3, c4, c5 = lay.motion_cross(vx, vy, vz, wx, wy, wz, sx, sy, sz, tx, ty, tz)
        ax, ay, az, bx, by, bz = ax + c0, ay + c1, az + c2, bx + c3, by + c4, bz + c5
        vx, vy, vz, wx, wy, wz = vx + sx, vy + sy, vz + sz, wx + tx, wy + ty, wz + tz
        f0, f1, f2, f3, f4, f5 = lay.body_times(p, work, k, ax, ay, az, bx, by, bz)
        m0, m1, m2, m3, m4, m5 = lay.body_times(p, work, k, vx, vy, vz, wx, wy, wz)
        g0, g1, g2, g3, g4, g5 = lay.force_cross(vx, vy, vz, wx, wy, wz, m0, m1, m2, m3, m4, m5)
        f = k * lay.WORK_STRIDE + lay.W_F
        work[f], work[f + 1], work[f + 2] = f0 + g0, f1 + g1, f2 + g2
        work[f + 3], work[f + 4], work[f + 5] = f3 + g3, f4 + g4, f5 + g5


@njit(**ALLOCATION_FREE)
def _add6(work, i, a0, a1, a2, a3, a4, a5):  # noqa: ANN001, ANN202, PLR0913
    """``(a0 + work[i], ..., a5 + work[i + 5])``: one step of a backward pass's running sum of
    six consecutive entries (a spatial force, or a rotational inertia)."""
    return (a0 + work[i], a1 + work[i + 1], a2 + work[i + 2],
            a3 + work[i + 3], a4 + work[i + 4], a5 + work[i + 5])


@njit(**ALLOCATION_FREE)
def _project_forces(p, out, work):  # noqa: ANN001, ANN202
    """RNEA's backward pass: ``out_k = S_k . (sum of the forces of bodies k..n-1)``."""
    n = int(p[lay.N_JOINTS])
    fx, fy, fz, nx, ny, nz = 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    for k in range(n - 1, -1, -1):
        fx, fy, fz, nx, ny, nz = _add6(work, k * lay.WORK_STRIDE + lay.W_F, fx, fy, fz, nx, ny, nz)
        out[k] = lay.dot_s(work, k, fx, fy, fz, nx, ny, nz)


# --------------------------------------------------------------------------- #
# The compiled form
# --------------------------------------------------------------------------- #
@njit(**ALLOCATION_FREE)
def terms(p, q, qd, mass, bias, work):  # noqa: ANN001, ANN201
    """``mass = M(q) + diag(J)`` (both triangles) and ``bias = C(q, qd) qd + G(q)``.

    CRBA and RNEA (``qdd = 0``, gravity included) share one kinematics pass and
    one backward pass: in base coordinates the composite inertia of bodies
    ``k..n-1`` is the plain sum of theirs, and ``M_ik = S_i . (I^c_k S_k)`` for
    ``i <= k``.
    """
    n = int(p[lay.N_JOINTS])
    kinematics_pass(p, q, work, 2)
    _bias_forces(p, qd, 1.0, work)
    cm = 0.0
    hx, hy, hz = 0.0, 0.0, 0.0
    ixx, iyy, izz, ixy, ixz, iyz = 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    fx, fy, fz, nx, ny, nz = 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    for k in range(n - 1, -1, -1):
        o = k * lay.WORK_STRIDE
        b = lay.HEADER_SIZE + k * lay.JOINT_SIZE
        cm += p[b + lay.J_MASS]
        h = o + lay.W_H
        hx, hy, hz = hx + work[h], hy + work[h + 1], hz + work[h + 2]
        ixx, iyy, izz, ixy, ixz, iyz = _add6(work, o + lay.W_IO, ixx, iyy, izz, ixy, ixz, iyz)
        fx, fy, fz, nx, ny, nz = _add6(work, o + lay.W_F, fx, fy, fz, nx, ny, nz)
        bias[k] = lay.dot_s(work, k, fx, fy, fz, nx, ny, nz)
        s = o + lay.W_S
        g0, g1, g2, g3, g4, g5 = lay.inertia_times(
            cm, hx, hy, hz, ixx, iyy, izz, ixy, ixz, iyz,
            work[s], work[s + 1], work[s + 2], work[s + 3], work[s + 4], work[s + 5],
        )
        for i in range(k):
            mik = lay.dot_s(work, i, g0, g1, g2, g3, g4, g5)
            mass[i, k] = mik
            mass[k, i] = mik
        mass[k, k] = lay.dot_s(work, k, g0, g1, g2, g3, g4, g5) + p[b + lay.J_ARMATURE]


@njit(**ALLOCATION_FREE)
def gravity(p, q, out, work):  # noqa: ANN001, ANN201
    """``G(q)``: the composite mass ``M_k`` and first moment ``H_k`` of bodies ``k..n-1`` hold
    ``(-M_k g, g x H_k)``, and ``G_k = S_k`` . that."""
    n = int(p[lay.N_JOINTS])
    kinematics_pass(p, q, work, 1)
    gx, gy, gz = p[lay.GRAVITY], p[lay.GRAVITY + 1], p[lay.GRAVITY + 2]
    cm = 0.0
    hx, hy, hz = 0.0, 0.0, 0.0
    for k in range(n - 1, -1, -1):
        o = k * lay.WORK_STRIDE + lay.W_H
        cm += p[lay.HEADER_SIZE + k * lay.JOINT_SIZE + lay.J_MASS]
        hx += work[o]
        hy += work[o + 1]
        hz += work[o + 2]
        nx, ny, nz = lay.cross(gx, gy, gz, hx, hy, hz)
        out[k] = lay.dot_s(work, k, -cm * gx, -cm * gy, -cm * gz, nx, ny, nz)


@njit(**ALLOCATION_FREE)
def coriolis_times(p, q, qd, v, out, work):  # noqa: ANN001, ANN201
    """``C(q, qd) v`` with the Christoffel-symbol ``C``.

    ``c(x) = C(q, x) x`` (RNEA without gravity) is a quadratic form in ``x`` and the
    Christoffel symbols are its symmetric bilinear form, so ``C(q, qd) v = B(qd, v)``
    with ``B`` the polarisation of ``c``. One RNEA-like pass evaluates ``B``
    directly, symmetrising each quadratic term: exact, and without the
    cancellation of ``(c(qd + v) - c(qd - v)) / 4``.
    """
    n = int(p[lay.N_JOINTS])
    kinematics_pass(p, q, work, 2)
    vx, vy, vz, wx, wy, wz = 0.0, 0.0, 0.0, 0.0, 0.0, 0.0  # velocity of x = qd
    ux, uy, uz, yx, yy, yz = 0.0, 0.0, 0.0, 0.0, 0.0, 0.0  # velocity of y = v
    ax, ay, az, bx, by, bz = 0.0, 0.0, 0.0, 0.0, 0.0, 0.0  # the bilinear acceleration
    for k in range(n):
        s = k * lay.WORK_STRIDE + lay.W_S
        xk = qd[k]
        yk = v[k]
        s0, s1, s2, s3, s4, s5 = work[s], work[s + 1], work[s + 2], work[s + 3], work[s + 4], work[s + 5]
        # a += (v_x x S y_k + v_y x S x_k) / 2 with the velocities of bodies 0..k-1
        c0, c1, c2, c3, c4, c5 = lay.motion_cross(vx, vy, vz, wx, wy, wz, s0 * yk, s1 * yk, s2 * yk,
                                               s3 * yk, s4 * yk, s5 * yk)
        d0, d1, d2, d3, d4, d5 = lay.motion_cross(ux, uy, uz, yx, yy, yz, s0 * xk, s1 * xk, s2 * xk,
                                               s3 * xk, s4 * xk, s5 * xk)
        ax += 0.5 * (c0 + d0)
        ay += 0.5 * (c1 + d1)
        az += 0.5 * (c2 + d2)
        bx += 0.5 * (c3 + d3)
        by += 0.5 * (c4 + d4)
        bz += 0.5 * (c5 + d5)
        vx, vy, vz, wx, wy, wz = vx + s0 * xk, vy + s1 * xk, vz + s2 * xk, wx + s3 * xk, wy + s4 * xk, wz + s5 * xk
        ux, uy, uz, yx, yy, yz = ux + s0 * yk, uy + s1 * yk, uz + s2 * yk, yx + s3 * yk, yy + s4 * yk, yz + s5 * yk
        # f = I a + (v_x x* I v_y + v_y x* I v_x) / 2
        f0, f1, f2, f3, f4, f5 = lay.body_times(p, work, k, ax, ay, az, bx, by, bz)
        m0, m1, m2, m3, m4, m5 = lay.body_times(p, work, k, ux, uy, uz, yx, yy, yz)
        g0, g1, g2, g3, g4, g5 = lay.force_cross(vx, vy, vz, wx, wy, wz, m0, m1, m2, m3, m4, m5)
        m0, m1, m2, m3, m4, m5 = lay.body_times(p, work, k, vx, vy, vz, wx, wy, wz)
        h0, h1, h2, h3, h4, h5 = lay.force_cross(ux, uy, uz, yx, yy, yz, m0, m1, m2, m3, m4, m5)
        f = k * lay.WORK_STRIDE + lay.W_F
        work[f] = f0 + 0.5 * (g0 + h0)
        work[f + 1] = f1 + 0.5 * (g1 + h1)
        work[f + 2] = f2 + 0.5 * (g2 + h2)
        work[f + 3] = f3 + 0.5 * (g3 + h3)
        work[f + 4] = f4 + 0.5 * (g4 + h4)
        work[f + 5] = f5 + 0.5 * (g5 + h5)
    _project_forces(p, out, work)


@njit(**ALLOCATION_FREE)
def accelerations(p, q, qd, tau, out, work):  # noqa: ANN001, ANN201
    """Eq. (4.1): ``qdd = Mbar^{-1} (tau - C qd - B qd - G)`` into ``out`` (:func:`terms`, then a
    Cholesky solve)."""
    n = q.shape[0]
    rhs = work[0:n]
    mass = work[n : n + n * n].reshape((n, n))
    rest = work[n + n * n :]
    terms(p, q, qd, mass, rhs, rest)
    for i in range(n):
        rhs[i] = tau[i] - rhs[i] - damping(p, i) * qd[i]
    solve_spd(mass, rhs, out, n)


@njit(**ALLOCATION_FREE)
def motor_inertia(p, i):  # noqa: ANN001, ANN201
    """Motor inertia ``J_i``."""
    return p[lay.HEADER_SIZE + i * lay.JOINT_SIZE + lay.J_ARMATURE]


@njit(**ALLOCATION_FREE)
def damping(p, i):  # noqa: ANN001, ANN201
    """Motor viscous damping ``B_i``."""
    return p[lay.HEADER_SIZE + i * lay.JOINT_SIZE + lay.J_DAMPING]
