"""Compiled step code: dynamics, RK4 and control laws for one state (numba).

:mod:`pdsmc_ros.models` is the readable, vectorised reference; this module is
the same mathematics written as scalar loops and compiled with numba, because a
10 kHz loop spends most of its time in per-call overhead when written with
small numpy arrays (about 200 us per serial forward-dynamics call against about
1 us here). Tests prove both agree to 1e-12.

The in-process simulator (:mod:`pdsmc_ros.simulator`) and the ROS nodes call
exactly these functions, which is why a lockstep DDS run and an in-process run
agree to rounding.

Robot parameters travel as flat ``float64`` arrays built by :func:`pack_robot`:

* serial 3R (``ROBOT_SERIAL``): ``W(9) w(3) I(3) L(3) J(3) B(3) g``
* five-bar (``ROBOT_FIVEBAR``): left chain ``W(4) w(2) I(2) L(2)``, right chain
  ``W(4) w(2) I(2) L(2)``, ``L5 J(2) B(2) g mode``
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .models import FloatArray, Manipulator, Parallel5R, PlanarChain, Serial3R

ROBOT_SERIAL = 0
ROBOT_FIVEBAR = 1

CTRL_PD = 0
CTRL_SMC = 1
CTRL_PDSMC = 2

_CACHE = True


def pack_robot(robot: Manipulator) -> tuple[int, FloatArray]:
    """Flat parameter array of ``robot`` for the kernels, with its kind code."""
    if isinstance(robot, Serial3R):
        c = robot.chain
        parts = [c.W.ravel(), c.w, c.inertias, c.lengths, robot.J, robot.B, [c.gravity]]
        return ROBOT_SERIAL, np.concatenate([np.asarray(x, dtype=float).ravel() for x in parts])
    if isinstance(robot, Parallel5R):
        parts = [
            *_chain_parts(robot.left),
            *_chain_parts(robot.right),
            [robot.L5],
            robot.J,
            robot.B,
            [robot.left.gravity, float(robot.assembly_mode)],
        ]
        return ROBOT_FIVEBAR, np.concatenate([np.asarray(x, dtype=float).ravel() for x in parts])
    raise TypeError(f"no kernel for robot type {type(robot).__name__}")


def _chain_parts(chain: PlanarChain) -> list[FloatArray]:
    return [chain.W.ravel(), chain.w, chain.inertias, chain.lengths]


# --------------------------------------------------------------------------- #
# Planar chain building blocks (n = 2 or 3)
# --------------------------------------------------------------------------- #
@njit(cache=_CACHE)
def _chain_mass_bias(W, w, inertia, g, q, qd, mass, bias):  # noqa: ANN001, ANN202
    """Link mass matrix and ``C qd + G`` of a planar chain (see PlanarChain).

    ``cos(theta_a - theta_b)`` and ``sin(theta_a - theta_b)`` come from the
    sines and cosines of the absolute angles (one pair per link).
    """
    n = q.shape[0]
    c = np.empty(n)
    s = np.empty(n)
    thd = np.empty(n)
    acc = 0.0
    accd = 0.0
    for a in range(n):
        acc += q[a]
        accd += qd[a]
        c[a] = math.cos(acc)
        s[a] = math.sin(acc)
        thd[a] = accd
    m_abs = np.empty((n, n))
    y = np.empty(n)
    for a in range(n):
        ya = g * w[a] * c[a]
        for b in range(n):
            wab = W[a * n + b]
            m_abs[a, b] = wab * (c[a] * c[b] + s[a] * s[b])
            ya += wab * (s[a] * c[b] - c[a] * s[b]) * thd[b] * thd[b]
        m_abs[a, a] += inertia[a]
        y[a] = ya
    for i in range(n):
        total = 0.0
        for a in range(i, n):
            total += y[a]
        bias[i] = total
        for j in range(i, n):
            total = 0.0
            for a in range(i, n):
                for b in range(j, n):
                    total += m_abs[a, b]
            mass[i, j] = total
            mass[j, i] = total


@njit(cache=_CACHE)
def _chain_coriolis_times(W, q, qd, v, out):  # noqa: ANN001, ANN202
    """``C(q, qd) v`` of a planar chain: ``L^T C_theta L v``."""
    n = q.shape[0]
    c = np.empty(n)
    s = np.empty(n)
    thd = np.empty(n)
    thv = np.empty(n)
    a0 = 0.0
    a1 = 0.0
    a2 = 0.0
    for a in range(n):
        a0 += q[a]
        a1 += qd[a]
        a2 += v[a]
        c[a] = math.cos(a0)
        s[a] = math.sin(a0)
        thd[a] = a1
        thv[a] = a2
    y = np.empty(n)
    for a in range(n):
        total = 0.0
        for b in range(n):
            total += W[a * n + b] * (s[a] * c[b] - c[a] * s[b]) * thd[b] * thv[b]
        y[a] = total
    for i in range(n):
        total = 0.0
        for a in range(i, n):
            total += y[a]
        out[i] = total


@njit(cache=_CACHE)
def _solve_spd(m, b, out):  # noqa: ANN001, ANN202
    """Solve ``m x = b`` for a small symmetric positive definite ``m`` (Cholesky)."""
    n = b.shape[0]
    lower = np.zeros((n, n))
    for i in range(n):
        for j in range(i + 1):
            s = m[i, j]
            for k in range(j):
                s -= lower[i, k] * lower[j, k]
            if i == j:
                lower[i, i] = math.sqrt(s)
            else:
                lower[i, j] = s / lower[j, j]
    y = np.empty(n)
    for i in range(n):
        s = b[i]
        for k in range(i):
            s -= lower[i, k] * y[k]
        y[i] = s / lower[i, i]
    for i in range(n - 1, -1, -1):
        s = y[i]
        for k in range(i + 1, n):
            s -= lower[k, i] * out[k]
        out[i] = s / lower[i, i]


# --------------------------------------------------------------------------- #
# Serial 3R
# --------------------------------------------------------------------------- #
@njit(cache=_CACHE)
def _serial_terms(p, q, qd, mass, bias):  # noqa: ANN001, ANN202
    """``Mbar = M + J`` and ``C qd + G`` of the serial arm."""
    _chain_mass_bias(p[0:9], p[9:12], p[12:15], p[24], q, qd, mass, bias)
    for i in range(3):
        mass[i, i] += p[18 + i]


@njit(cache=_CACHE)
def _serial_gravity(p, q, out):  # noqa: ANN001, ANN202
    acc = 0.0
    y = np.empty(3)
    for a in range(3):
        acc += q[a]
        y[a] = p[24] * p[9 + a] * math.cos(acc)
    for i in range(3):
        s = 0.0
        for a in range(i, 3):
            s += y[a]
        out[i] = s


# --------------------------------------------------------------------------- #
# Five-bar (reduced model, Appendix Eqs. 47-70)
# --------------------------------------------------------------------------- #
@njit(cache=_CACHE)
def _fivebar_geometry(p, q, qd, ql, qr, qdl, qdr, rho, adot_p):  # noqa: ANN001, ANN202
    """Open-tree angles/rates and ``R = d(q3, q4)/d(q1, q2)``.

    Fills ``ql = (q1, q3)``, ``qr = (q2, q4)`` and their rates, ``rho`` (2x2,
    rows q3, q4) and ``adot_p`` with ``A_pas^{-1}`` (2x2) for later use.
    """
    l1 = p[8]
    l3 = p[9]
    l2 = p[18]
    l4 = p[19]
    l5 = p[20]
    mode = p[26]
    c1 = math.cos(q[0])
    s1 = math.sin(q[0])
    c2 = math.cos(q[1])
    s2 = math.sin(q[1])
    a1x = l1 * c1
    a1y = l1 * s1
    a2x = l5 + l2 * c2
    a2y = l2 * s2
    ux = a2x - a1x
    uy = a2y - a1y
    d2 = ux * ux + uy * uy
    d = math.sqrt(d2)
    along = (d2 + l3 * l3 - l4 * l4) / (2.0 * d)
    h = math.sqrt(max(l3 * l3 - along * along, 0.0))
    ex = ux / d
    ey = uy / d
    px = a1x + along * ex - mode * h * ey
    py = a1y + along * ey + mode * h * ex
    th13 = math.atan2(py - a1y, px - a1x)
    th24 = math.atan2(py - a2y, px - a2x)
    ql[0] = q[0]
    ql[1] = th13 - q[0]
    qr[0] = q[1]
    qr[1] = th24 - q[1]
    s13 = math.sin(th13)
    c13 = math.cos(th13)
    s24 = math.sin(th24)
    c24 = math.cos(th24)
    # tip Jacobians of both chains
    jl00 = -l1 * s1 - l3 * s13
    jl01 = -l3 * s13
    jl10 = l1 * c1 + l3 * c13
    jl11 = l3 * c13
    jr00 = -l2 * s2 - l4 * s24
    jr01 = -l4 * s24
    jr10 = l2 * c2 + l4 * c24
    jr11 = l4 * c24
    # A_act = [[jl00, -jr00], [jl10, -jr10]], A_pas = [[jl01, -jr01], [jl11, -jr11]]
    det = jl01 * (-jr11) - (-jr01) * jl11
    i00 = -jr11 / det
    i01 = jr01 / det
    i10 = -jl11 / det
    i11 = jl01 / det
    adot_p[0, 0] = i00
    adot_p[0, 1] = i01
    adot_p[1, 0] = i10
    adot_p[1, 1] = i11
    rho[0, 0] = -(i00 * jl00 + i01 * jl10)
    rho[0, 1] = -(i00 * (-jr00) + i01 * (-jr10))
    rho[1, 0] = -(i10 * jl00 + i11 * jl10)
    rho[1, 1] = -(i10 * (-jr00) + i11 * (-jr10))
    qdl[0] = qd[0]
    qdl[1] = rho[0, 0] * qd[0] + rho[0, 1] * qd[1]
    qdr[0] = qd[1]
    qdr[1] = rho[1, 0] * qd[0] + rho[1, 1] * qd[1]


@njit(cache=_CACHE)
def _fivebar_jdot_times(p, ql, qr, qdl, qdr, vl, vr, out):  # noqa: ANN001, ANN202
    """``Jdot_left vl - Jdot_right vr`` (rates of the constraint), 2-vector."""
    l1 = p[8]
    l3 = p[9]
    l2 = p[18]
    l4 = p[19]
    th1 = ql[0]
    th13 = ql[0] + ql[1]
    w1 = qdl[0]
    w13 = qdl[0] + qdl[1]
    th2 = qr[0]
    th24 = qr[0] + qr[1]
    w2 = qdr[0]
    w24 = qdr[0] + qdr[1]
    # Jdot of a 2-link chain: [[-l1 c1 w1 - l3 c13 w13, -l3 c13 w13], [-l1 s1 w1 - l3 s13 w13, -l3 s13 w13]]
    lx = (-l1 * math.cos(th1) * w1 - l3 * math.cos(th13) * w13) * vl[0] - l3 * math.cos(
        th13
    ) * w13 * vl[1]
    ly = (-l1 * math.sin(th1) * w1 - l3 * math.sin(th13) * w13) * vl[0] - l3 * math.sin(
        th13
    ) * w13 * vl[1]
    rx = (-l2 * math.cos(th2) * w2 - l4 * math.cos(th24) * w24) * vr[0] - l4 * math.cos(
        th24
    ) * w24 * vr[1]
    ry = (-l2 * math.sin(th2) * w2 - l4 * math.sin(th24) * w24) * vr[0] - l4 * math.sin(
        th24
    ) * w24 * vr[1]
    out[0] = lx - rx
    out[1] = ly - ry


@njit(cache=_CACHE)
def _fivebar_terms(p, q, qd, mass, bias):  # noqa: ANN001, ANN202
    """Reduced ``Mbar`` and ``C qd + G`` of the five-bar."""
    ql = np.empty(2)
    qr = np.empty(2)
    qdl = np.empty(2)
    qdr = np.empty(2)
    rho = np.empty((2, 2))
    ainv = np.empty((2, 2))
    _fivebar_geometry(p, q, qd, ql, qr, qdl, qdr, rho, ainv)
    ml = np.empty((2, 2))
    mr = np.empty((2, 2))
    bl = np.empty(2)
    br = np.empty(2)
    _chain_mass_bias(p[0:4], p[4:6], p[6:8], p[25], ql, qdl, ml, bl)
    _chain_mass_bias(p[10:14], p[14:16], p[16:18], p[25], qr, qdr, mr, br)
    cdot = np.empty(2)
    _fivebar_jdot_times(p, ql, qr, qdl, qdr, qdl, qdr, cdot)
    pas0 = -(ainv[0, 0] * cdot[0] + ainv[0, 1] * cdot[1])  # (rhodot qd) for q3
    pas1 = -(ainv[1, 0] * cdot[0] + ainv[1, 1] * cdot[1])  # (rhodot qd) for q4
    # f = C' qd' + M' rhodot qd + G' per chain
    fl0 = bl[0] + ml[0, 1] * pas0
    fl1 = bl[1] + ml[1, 1] * pas0
    fr0 = br[0] + mr[0, 1] * pas1
    fr1 = br[1] + mr[1, 1] * pas1
    # rho_left = [[1, 0], [r00, r01]], rho_right = [[0, 1], [r10, r11]]
    r00 = rho[0, 0]
    r01 = rho[0, 1]
    r10 = rho[1, 0]
    r11 = rho[1, 1]
    bias[0] = fl0 + r00 * fl1 + r10 * fr1
    bias[1] = r01 * fl1 + fr0 + r11 * fr1
    # rho^T M rho for each chain
    m00 = ml[0, 0] + 2.0 * r00 * ml[0, 1] + r00 * r00 * ml[1, 1]
    m01 = r01 * ml[0, 1] + r00 * r01 * ml[1, 1]
    m11 = r01 * r01 * ml[1, 1]
    m00 += r10 * r10 * mr[1, 1]
    m01 += r10 * mr[0, 1] + r10 * r11 * mr[1, 1]
    m11 += mr[0, 0] + 2.0 * r11 * mr[0, 1] + r11 * r11 * mr[1, 1]
    mass[0, 0] = m00 + p[21]
    mass[0, 1] = m01
    mass[1, 0] = m01
    mass[1, 1] = m11 + p[22]


@njit(cache=_CACHE)
def _fivebar_coriolis_times(p, q, qd, v, out):  # noqa: ANN001, ANN202
    """``C(q, qd) v`` of the reduced model, ``C = rho^T C' rho + rho^T M' rhodot``."""
    ql = np.empty(2)
    qr = np.empty(2)
    qdl = np.empty(2)
    qdr = np.empty(2)
    rho = np.empty((2, 2))
    ainv = np.empty((2, 2))
    _fivebar_geometry(p, q, qd, ql, qr, qdl, qdr, rho, ainv)
    vl = np.empty(2)
    vr = np.empty(2)
    vl[0] = v[0]
    vl[1] = rho[0, 0] * v[0] + rho[0, 1] * v[1]
    vr[0] = v[1]
    vr[1] = rho[1, 0] * v[0] + rho[1, 1] * v[1]
    cl = np.empty(2)
    cr = np.empty(2)
    _chain_coriolis_times(p[0:4], ql, qdl, vl, cl)
    _chain_coriolis_times(p[10:14], qr, qdr, vr, cr)
    cdot = np.empty(2)
    _fivebar_jdot_times(p, ql, qr, qdl, qdr, vl, vr, cdot)
    pas0 = -(ainv[0, 0] * cdot[0] + ainv[0, 1] * cdot[1])
    pas1 = -(ainv[1, 0] * cdot[0] + ainv[1, 1] * cdot[1])
    ml = np.empty((2, 2))
    mr = np.empty((2, 2))
    dummy = np.empty(2)
    _chain_mass_bias(p[0:4], p[4:6], p[6:8], 0.0, ql, qdl, ml, dummy)
    _chain_mass_bias(p[10:14], p[14:16], p[16:18], 0.0, qr, qdr, mr, dummy)
    fl0 = cl[0] + ml[0, 1] * pas0
    fl1 = cl[1] + ml[1, 1] * pas0
    fr0 = cr[0] + mr[0, 1] * pas1
    fr1 = cr[1] + mr[1, 1] * pas1
    out[0] = fl0 + rho[0, 0] * fl1 + rho[1, 0] * fr1
    out[1] = rho[0, 1] * fl1 + fr0 + rho[1, 1] * fr1


@njit(cache=_CACHE)
def _fivebar_gravity(p, q, out):  # noqa: ANN001, ANN202
    mass = np.empty((2, 2))
    _fivebar_terms(p, q, np.zeros(2), mass, out)


# --------------------------------------------------------------------------- #
# Dispatch on robot kind
# --------------------------------------------------------------------------- #
@njit(cache=_CACHE)
def robot_terms(kind, p, q, qd, mass, bias):  # noqa: ANN001, ANN201
    """``Mbar(q)`` and ``C(q, qd) qd + G(q)``."""
    if kind == ROBOT_SERIAL:
        _serial_terms(p, q, qd, mass, bias)
    else:
        _fivebar_terms(p, q, qd, mass, bias)


@njit(cache=_CACHE)
def robot_coriolis_times(kind, p, q, qd, v, out):  # noqa: ANN001, ANN201
    """``C(q, qd) v``."""
    if kind == ROBOT_SERIAL:
        _chain_coriolis_times(p[0:9], q, qd, v, out)
    else:
        _fivebar_coriolis_times(p, q, qd, v, out)


@njit(cache=_CACHE)
def robot_gravity(kind, p, q, out):  # noqa: ANN001, ANN201
    """``G(q)``."""
    if kind == ROBOT_SERIAL:
        _serial_gravity(p, q, out)
    else:
        _fivebar_gravity(p, q, out)


@njit(cache=_CACHE)
def _damping(kind, p, i):  # noqa: ANN001, ANN202
    if kind == ROBOT_SERIAL:
        return p[21 + i]
    return p[23 + i]


@njit(cache=_CACHE)
def _motor_inertia(kind, p, i):  # noqa: ANN001, ANN202
    if kind == ROBOT_SERIAL:
        return p[18 + i]
    return p[21 + i]


@njit(cache=_CACHE)
def forward_dynamics(kind, p, q, qd, tau, out):  # noqa: ANN001, ANN201
    """Eq. (4.1): ``qdd = Mbar^{-1} (tau - C qd - B qd - G)`` into ``out``."""
    n = q.shape[0]
    mass = np.empty((n, n))
    bias = np.empty(n)
    robot_terms(kind, p, q, qd, mass, bias)
    rhs = np.empty(n)
    for i in range(n):
        rhs[i] = tau[i] - bias[i] - _damping(kind, p, i) * qd[i]
    _solve_spd(mass, rhs, out)


@njit(cache=_CACHE)
def rk4_step(kind, p, q, qd, tau, h, q_out, qd_out):  # noqa: ANN001, ANN201
    """One classical RK4 step of Eq. (4.1) with ``tau`` held (zero-order hold).

    Same arithmetic, in the same order, as :func:`pdsmc_ros.integrators.rk4_step`.
    """
    n = q.shape[0]
    half = 0.5 * h
    a1 = np.empty(n)
    a2 = np.empty(n)
    a3 = np.empty(n)
    a4 = np.empty(n)
    v2 = np.empty(n)
    v3 = np.empty(n)
    v4 = np.empty(n)
    x = np.empty(n)
    forward_dynamics(kind, p, q, qd, tau, a1)
    for i in range(n):
        v2[i] = qd[i] + half * a1[i]
        x[i] = q[i] + half * qd[i]
    forward_dynamics(kind, p, x, v2, tau, a2)
    for i in range(n):
        v3[i] = qd[i] + half * a2[i]
        x[i] = q[i] + half * v2[i]
    forward_dynamics(kind, p, x, v3, tau, a3)
    for i in range(n):
        v4[i] = qd[i] + h * a3[i]
        x[i] = q[i] + h * v3[i]
    forward_dynamics(kind, p, x, v4, tau, a4)
    sixth = h / 6.0
    for i in range(n):
        q_out[i] = q[i] + sixth * (qd[i] + 2.0 * v2[i] + 2.0 * v3[i] + v4[i])
        qd_out[i] = qd[i] + sixth * (a1[i] + 2.0 * a2[i] + 2.0 * a3[i] + a4[i])


# --------------------------------------------------------------------------- #
# Control laws (Chapter 3)
# --------------------------------------------------------------------------- #
@njit(cache=_CACHE)
def control_torque(  # noqa: ANN201, PLR0913
    ctrl, gains, model, kind, p, q, qd, q_ref, qd_ref, qdd_ref, tau
):  # noqa: ANN001
    """Torque of the PD (Eq. 3.4), SMC (Eq. 3.15) or PD-SMC (Eq. 3.44) law.

    Parameters
    ----------
    ctrl : int
        ``CTRL_PD``, ``CTRL_SMC`` or ``CTRL_PDSMC``.
    gains : ndarray, shape (5, n)
        Rows ``kp, kd, ks, lambda, phi`` (unused rows ignored by the law).
    model : ndarray, shape (6,)
        SMC model estimate ``(s_M, s_C, s_G, s_B, motor_inertia, at_desired)``
        applied to the *nominal* model ``(kind, p)``: ``Mhat = s_M Mbar``
        (``s_M M`` if ``motor_inertia == 0``), ``Chat = s_C C``,
        ``Ghat = s_G G``, plus ``s_B B qd_r``; evaluated at the measured state,
        or at the desired one if ``at_desired == 1``.
    kind, p : int, ndarray
        Model known to the SMC (from :func:`pack_robot`).

    Notes
    -----
    With ``e = q_d - q`` (Eq. 3.2) and ``s = lambda e + edot``, the SMC of
    Eq. (3.15), written with the thesis's ``e' = q - q_d`` (Eq. 3.5), is
    ``Mhat (qdd_d + lambda edot) + Chat (qd_d + lambda e) + Ghat + Ks sat(s/phi)``
    because ``s' = -s``; the PD-SMC of Eq. (3.44) is
    ``Kp e + Kd edot + Ks sat(s/phi)``; the boundary layer is Eq. (3.45).
    """
    n = q.shape[0]
    e = np.empty(n)
    ed = np.empty(n)
    sat = np.empty(n)
    for i in range(n):
        e[i] = q_ref[i] - q[i]
        ed[i] = qd_ref[i] - qd[i]
        s = (gains[3, i] * e[i] + ed[i]) / gains[4, i]
        if s > 1.0:
            s = 1.0
        elif s < -1.0:
            s = -1.0
        sat[i] = s
    if ctrl == CTRL_PD:
        for i in range(n):
            tau[i] = gains[0, i] * e[i] + gains[1, i] * ed[i]
    elif ctrl == CTRL_PDSMC:
        for i in range(n):
            tau[i] = gains[0, i] * e[i] + gains[1, i] * ed[i] + gains[2, i] * sat[i]
    else:
        # model evaluated at the measured state, or at the desired one (model[5] = 1)
        qm = q
        qdm = qd
        if model[5] != 0.0:
            qm = q_ref
            qdm = qd_ref
        mass = np.empty((n, n))
        bias = np.empty(n)
        robot_terms(kind, p, qm, qdm, mass, bias)
        if model[4] == 0.0:  # motor inertia not part of the estimate
            for i in range(n):
                mass[i, i] -= _motor_inertia(kind, p, i)
        grav = np.empty(n)
        robot_gravity(kind, p, qm, grav)
        qdd_r = np.empty(n)
        qd_r = np.empty(n)
        for i in range(n):
            qdd_r[i] = qdd_ref[i] + gains[3, i] * ed[i]
            qd_r[i] = qd_ref[i] + gains[3, i] * e[i]
        cor = np.empty(n)
        robot_coriolis_times(kind, p, qm, qdm, qd_r, cor)
        for i in range(n):
            acc = 0.0
            for j in range(n):
                acc += mass[i, j] * qdd_r[j]
            tau[i] = (
                model[0] * acc
                + model[1] * cor[i]
                + model[2] * grav[i]
                + model[3] * _damping(kind, p, i) * qd_r[i]
                + gains[2, i] * sat[i]
            )


# --------------------------------------------------------------------------- #
# Whole run (in-process simulator)
# --------------------------------------------------------------------------- #
@njit(cache=_CACHE)
def run_closed_loop(  # noqa: ANN201, PLR0913
    kind, p, ctrl, gains, model, model_kind, model_p, q0, qd0, refs, h, sample_every,
    out_q, out_qd, out_tau,
):  # noqa: ANN001
    """Discrete closed loop: control at each step, RK4 plant in between.

    ``refs`` has shape ``(N + 1, 3, n)`` (q, qd, qdd of the reference at the
    control instants). Every ``sample_every``-th instant, the state and the
    torque computed at that instant are written to the outputs.
    """
    n = q0.shape[0]
    steps = refs.shape[0] - 1
    q = q0.copy()
    qd = qd0.copy()
    q_next = np.empty(n)
    qd_next = np.empty(n)
    tau = np.empty(n)
    for k in range(steps + 1):
        control_torque(
            ctrl, gains, model, model_kind, model_p, q, qd, refs[k, 0], refs[k, 1], refs[k, 2], tau
        )
        if k % sample_every == 0:
            j = k // sample_every
            for i in range(n):
                out_q[j, i] = q[i]
                out_qd[j, i] = qd[i]
                out_tau[j, i] = tau[i]
        if k < steps:
            rk4_step(kind, p, q, qd, tau, h, q_next, qd_next)
            for i in range(n):
                q[i] = q_next[i]
                qd[i] = qd_next[i]
