"""Compiled step code: dynamics, RK4 and control laws for one state (numba).

:mod:`pdsmc_ros.models` is the readable, vectorised reference; this module is
the same mathematics written as scalar loops and compiled with numba, because a
10 kHz loop spends most of its time in per-call overhead when written with
small numpy arrays (about 200 us per serial forward-dynamics call against about
1 us here). Tests prove both agree to 1e-12. The kernels allocate nothing:
temporaries live in a caller-owned scratch array (:func:`workspace`), which
halved the time per step (serial PD 9.9 -> 5.8 us, five-bar PD 19.0 -> 9.6 us).

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
#
# Every kernel takes a scratch array ``w`` (see :func:`workspace`) and carves its
# temporaries out of it, passing the rest on to the kernels it calls: the hot
# loop then allocates nothing (about half the time of a step went to small
# allocations before).
# --------------------------------------------------------------------------- #
WORK_SIZE = 128


def workspace() -> FloatArray:
    """Scratch array for the kernels of this module."""
    return np.empty(WORK_SIZE)


@njit(cache=_CACHE)
def _chain_mass_bias(W, w, inertia, g, q, qd, mass, bias, work):  # noqa: ANN001, ANN202
    """Link mass matrix and ``C qd + G`` of a planar chain (see PlanarChain).

    ``cos(theta_a - theta_b)`` and ``sin(theta_a - theta_b)`` come from the
    sines and cosines of the absolute angles (one pair per link).
    """
    n = q.shape[0]
    c = work[0:n]
    s = work[n : 2 * n]
    thd = work[2 * n : 3 * n]
    y = work[3 * n : 4 * n]
    m_abs = work[4 * n : 4 * n + n * n]  # row-major n x n
    acc = 0.0
    accd = 0.0
    for a in range(n):
        acc += q[a]
        accd += qd[a]
        c[a] = math.cos(acc)
        s[a] = math.sin(acc)
        thd[a] = accd
    for a in range(n):
        ya = g * w[a] * c[a]
        for b in range(n):
            wab = W[a * n + b]
            m_abs[a * n + b] = wab * (c[a] * c[b] + s[a] * s[b])
            ya += wab * (s[a] * c[b] - c[a] * s[b]) * thd[b] * thd[b]
        m_abs[a * n + a] += inertia[a]
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
                    total += m_abs[a * n + b]
            mass[i, j] = total
            mass[j, i] = total


@njit(cache=_CACHE)
def _chain_coriolis_times(W, q, qd, v, out, work):  # noqa: ANN001, ANN202
    """``C(q, qd) v`` of a planar chain: ``L^T C_theta L v``."""
    n = q.shape[0]
    c = work[0:n]
    s = work[n : 2 * n]
    thd = work[2 * n : 3 * n]
    thv = work[3 * n : 4 * n]
    y = work[4 * n : 5 * n]
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
def _solve_spd(m, b, out, work):  # noqa: ANN001, ANN202
    """Solve ``m x = b`` for a small symmetric positive definite ``m`` (Cholesky)."""
    n = b.shape[0]
    lower = work[0 : n * n]  # row-major; only the lower triangle is used
    y = work[n * n : n * n + n]
    for i in range(n):
        for j in range(i + 1):
            s = m[i, j]
            for k in range(j):
                s -= lower[i * n + k] * lower[j * n + k]
            if i == j:
                lower[i * n + i] = math.sqrt(s)
            else:
                lower[i * n + j] = s / lower[j * n + j]
    for i in range(n):
        s = b[i]
        for k in range(i):
            s -= lower[i * n + k] * y[k]
        y[i] = s / lower[i * n + i]
    for i in range(n - 1, -1, -1):
        s = y[i]
        for k in range(i + 1, n):
            s -= lower[k * n + i] * out[k]
        out[i] = s / lower[i * n + i]


# --------------------------------------------------------------------------- #
# Serial 3R
# --------------------------------------------------------------------------- #
@njit(cache=_CACHE)
def _serial_terms(p, q, qd, mass, bias, work):  # noqa: ANN001, ANN202
    """``Mbar = M + J`` and ``C qd + G`` of the serial arm."""
    _chain_mass_bias(p[0:9], p[9:12], p[12:15], p[24], q, qd, mass, bias, work)
    for i in range(3):
        mass[i, i] += p[18 + i]


@njit(cache=_CACHE)
def _serial_gravity(p, q, out):  # noqa: ANN001, ANN202
    acc = 0.0
    for i in range(3):
        out[i] = 0.0
    for a in range(3):
        acc += q[a]
        ya = p[24] * p[9 + a] * math.cos(acc)
        for i in range(a + 1):
            out[i] += ya


# --------------------------------------------------------------------------- #
# Five-bar (reduced model, Appendix Eqs. 47-70)
# --------------------------------------------------------------------------- #
FIVEBAR_GEOMETRY_SIZE = 16


@njit(cache=_CACHE)
def _fivebar_geometry(p, q, qd, geo):  # noqa: ANN001, ANN202
    """Open-tree angles/rates and ``R = d(q3, q4)/d(q1, q2)`` into ``geo``.

    ``geo`` (16 floats) receives ``ql = (q1, q3)`` [0:2], ``qr = (q2, q4)``
    [2:4], their rates ``qdl`` [4:6] and ``qdr`` [6:8], ``rho`` [8:12]
    (row-major 2x2, rows q3, q4) and ``A_pas^{-1}`` [12:16] (row-major 2x2).
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
    geo[0] = q[0]
    geo[1] = th13 - q[0]
    geo[2] = q[1]
    geo[3] = th24 - q[1]
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
    geo[12] = i00
    geo[13] = i01
    geo[14] = i10
    geo[15] = i11
    r00 = -(i00 * jl00 + i01 * jl10)
    r01 = -(i00 * (-jr00) + i01 * (-jr10))
    r10 = -(i10 * jl00 + i11 * jl10)
    r11 = -(i10 * (-jr00) + i11 * (-jr10))
    geo[8] = r00
    geo[9] = r01
    geo[10] = r10
    geo[11] = r11
    geo[4] = qd[0]
    geo[5] = r00 * qd[0] + r01 * qd[1]
    geo[6] = qd[1]
    geo[7] = r10 * qd[0] + r11 * qd[1]


@njit(cache=_CACHE)
def _fivebar_jdot_times(p, geo, vl0, vl1, vr0, vr1):  # noqa: ANN001, ANN202
    """``Jdot_left vl - Jdot_right vr`` (rates of the constraint), as two floats."""
    l1 = p[8]
    l3 = p[9]
    l2 = p[18]
    l4 = p[19]
    th1 = geo[0]
    th13 = geo[0] + geo[1]
    w1 = geo[4]
    w13 = geo[4] + geo[5]
    th2 = geo[2]
    th24 = geo[2] + geo[3]
    w2 = geo[6]
    w24 = geo[6] + geo[7]
    # Jdot of a 2-link chain: [[-l1 c1 w1 - l3 c13 w13, -l3 c13 w13], [-l1 s1 w1 - l3 s13 w13, -l3 s13 w13]]
    lx = (-l1 * math.cos(th1) * w1 - l3 * math.cos(th13) * w13) * vl0 - l3 * math.cos(
        th13
    ) * w13 * vl1
    ly = (-l1 * math.sin(th1) * w1 - l3 * math.sin(th13) * w13) * vl0 - l3 * math.sin(
        th13
    ) * w13 * vl1
    rx = (-l2 * math.cos(th2) * w2 - l4 * math.cos(th24) * w24) * vr0 - l4 * math.cos(
        th24
    ) * w24 * vr1
    ry = (-l2 * math.sin(th2) * w2 - l4 * math.sin(th24) * w24) * vr0 - l4 * math.sin(
        th24
    ) * w24 * vr1
    return lx - rx, ly - ry


@njit(cache=_CACHE)
def _fivebar_chain_terms(p, geo, g, ml, mr, bl, br, work):  # noqa: ANN001, ANN202
    """Mass matrices and ``C' qd' + G'`` of both open chains at ``geo``."""
    _chain_mass_bias(p[0:4], p[4:6], p[6:8], g, geo[0:2], geo[4:6], ml, bl, work)
    _chain_mass_bias(p[10:14], p[14:16], p[16:18], g, geo[2:4], geo[6:8], mr, br, work)


@njit(cache=_CACHE)
def _fivebar_passive_rates(geo, cdot0, cdot1):  # noqa: ANN001, ANN202
    """``rhodot qd`` for (q3, q4) from the constraint rates: ``-A_pas^{-1} cdot``."""
    pas0 = -(geo[12] * cdot0 + geo[13] * cdot1)
    pas1 = -(geo[14] * cdot0 + geo[15] * cdot1)
    return pas0, pas1


@njit(cache=_CACHE)
def _fivebar_terms(p, q, qd, mass, bias, work):  # noqa: ANN001, ANN202
    """Reduced ``Mbar`` and ``C qd + G`` of the five-bar."""
    geo = work[0:FIVEBAR_GEOMETRY_SIZE]
    _fivebar_geometry(p, q, qd, geo)
    ml = work[16:20].reshape((2, 2))
    mr = work[20:24].reshape((2, 2))
    bl = work[24:26]
    br = work[26:28]
    _fivebar_chain_terms(p, geo, p[25], ml, mr, bl, br, work[28:])
    cdot0, cdot1 = _fivebar_jdot_times(p, geo, geo[4], geo[5], geo[6], geo[7])
    pas0, pas1 = _fivebar_passive_rates(geo, cdot0, cdot1)
    # f = C' qd' + M' rhodot qd + G' per chain
    fl0 = bl[0] + ml[0, 1] * pas0
    fl1 = bl[1] + ml[1, 1] * pas0
    fr0 = br[0] + mr[0, 1] * pas1
    fr1 = br[1] + mr[1, 1] * pas1
    # rho_left = [[1, 0], [r00, r01]], rho_right = [[0, 1], [r10, r11]]
    r00 = geo[8]
    r01 = geo[9]
    r10 = geo[10]
    r11 = geo[11]
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
def _fivebar_coriolis_times(p, q, qd, v, out, work):  # noqa: ANN001, ANN202
    """``C(q, qd) v`` of the reduced model, ``C = rho^T C' rho + rho^T M' rhodot``."""
    geo = work[0:FIVEBAR_GEOMETRY_SIZE]
    _fivebar_geometry(p, q, qd, geo)
    rho = geo[8:12]
    vl = work[16:18]
    vr = work[18:20]
    vl[0] = v[0]
    vl[1] = rho[0] * v[0] + rho[1] * v[1]
    vr[0] = v[1]
    vr[1] = rho[2] * v[0] + rho[3] * v[1]
    cl = work[20:22]
    cr = work[22:24]
    _chain_coriolis_times(p[0:4], geo[0:2], geo[4:6], vl, cl, work[40:])
    _chain_coriolis_times(p[10:14], geo[2:4], geo[6:8], vr, cr, work[40:])
    cdot0, cdot1 = _fivebar_jdot_times(p, geo, vl[0], vl[1], vr[0], vr[1])
    pas0, pas1 = _fivebar_passive_rates(geo, cdot0, cdot1)
    ml = work[24:28].reshape((2, 2))
    mr = work[28:32].reshape((2, 2))
    _fivebar_chain_terms(p, geo, 0.0, ml, mr, work[32:34], work[34:36], work[40:])
    fl0 = cl[0] + ml[0, 1] * pas0
    fl1 = cl[1] + ml[1, 1] * pas0
    fr0 = cr[0] + mr[0, 1] * pas1
    fr1 = cr[1] + mr[1, 1] * pas1
    out[0] = fl0 + rho[0] * fl1 + rho[2] * fr1
    out[1] = rho[1] * fl1 + fr0 + rho[3] * fr1


@njit(cache=_CACHE)
def _fivebar_gravity(p, q, out, work):  # noqa: ANN001, ANN202
    mass = work[0:4].reshape((2, 2))
    qd = work[4:6]
    qd[0] = 0.0
    qd[1] = 0.0
    _fivebar_terms(p, q, qd, mass, out, work[6:])


# --------------------------------------------------------------------------- #
# Dispatch on robot kind
# --------------------------------------------------------------------------- #
@njit(cache=_CACHE)
def robot_terms(kind, p, q, qd, mass, bias, work):  # noqa: ANN001, ANN201
    """``Mbar(q)`` and ``C(q, qd) qd + G(q)``."""
    if kind == ROBOT_SERIAL:
        _serial_terms(p, q, qd, mass, bias, work)
    else:
        _fivebar_terms(p, q, qd, mass, bias, work)


@njit(cache=_CACHE)
def robot_coriolis_times(kind, p, q, qd, v, out, work):  # noqa: ANN001, ANN201
    """``C(q, qd) v``."""
    if kind == ROBOT_SERIAL:
        _chain_coriolis_times(p[0:9], q, qd, v, out, work)
    else:
        _fivebar_coriolis_times(p, q, qd, v, out, work)


@njit(cache=_CACHE)
def robot_gravity(kind, p, q, out, work):  # noqa: ANN001, ANN201
    """``G(q)``."""
    if kind == ROBOT_SERIAL:
        _serial_gravity(p, q, out)
    else:
        _fivebar_gravity(p, q, out, work)


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
def forward_dynamics(kind, p, q, qd, tau, out, work):  # noqa: ANN001, ANN201
    """Eq. (4.1): ``qdd = Mbar^{-1} (tau - C qd - B qd - G)`` into ``out``."""
    n = q.shape[0]
    mass = work[0 : n * n].reshape((n, n))
    bias = work[9:12]
    rhs = work[12:15]
    robot_terms(kind, p, q, qd, mass, bias, work[16:])
    for i in range(n):
        rhs[i] = tau[i] - bias[i] - _damping(kind, p, i) * qd[i]
    _solve_spd(mass, rhs[0:n], out, work[16:])


OUTPUTS_SIZE = 6


@njit(cache=_CACHE)
def robot_outputs(kind, p, q, qd, out, work):  # noqa: ANN001, ANN201
    """What the plant reports besides ``q``, ``qd``, into ``out`` (``OUTPUTS_SIZE`` floats).

    ``out[0:2]``: end-effector ``(x, y)`` (serial: ``PlanarChain.tip`` with the
    base at the origin; five-bar: Appendix Eqs. 26-34). Five-bar only:
    ``out[2:4]`` the passive joints ``(q3, q4)`` wrapped to (-pi, pi] and
    ``out[4:6]`` their rates (Eq. 3 of the reduced model, ``rho qd``). One call
    instead of a dozen small numpy operations per published state.
    """
    if kind == ROBOT_SERIAL:
        acc = 0.0
        x = 0.0
        y = 0.0
        for a in range(3):
            acc += q[a]
            x += p[15 + a] * math.cos(acc)
            y += p[15 + a] * math.sin(acc)
        out[0] = x
        out[1] = y
        return
    geo = work[0:FIVEBAR_GEOMETRY_SIZE]
    _fivebar_geometry(p, q, qd, geo)
    th13 = geo[0] + geo[1]
    out[0] = p[8] * math.cos(geo[0]) + p[9] * math.cos(th13)
    out[1] = p[8] * math.sin(geo[0]) + p[9] * math.sin(th13)
    for i in range(2):
        angle = geo[1 + 2 * i]
        out[2 + i] = math.pi - (math.pi - angle) % (2.0 * math.pi)
        out[4 + i] = geo[5 + 2 * i]


@njit(cache=_CACHE)
def rk4_step(kind, p, q, qd, tau, h, q_out, qd_out, work):  # noqa: ANN001, ANN201
    """One classical RK4 step of Eq. (4.1) with ``tau`` held (zero-order hold).

    Same arithmetic, in the same order, as :func:`pdsmc_ros.integrators.rk4_step`.
    """
    n = q.shape[0]
    half = 0.5 * h
    a1 = work[0:n]
    a2 = work[3 : 3 + n]
    a3 = work[6 : 6 + n]
    a4 = work[9 : 9 + n]
    v2 = work[12 : 12 + n]
    v3 = work[15 : 15 + n]
    v4 = work[18 : 18 + n]
    x = work[21 : 21 + n]
    rest = work[24:]
    forward_dynamics(kind, p, q, qd, tau, a1, rest)
    for i in range(n):
        v2[i] = qd[i] + half * a1[i]
        x[i] = q[i] + half * qd[i]
    forward_dynamics(kind, p, x, v2, tau, a2, rest)
    for i in range(n):
        v3[i] = qd[i] + half * a2[i]
        x[i] = q[i] + half * v2[i]
    forward_dynamics(kind, p, x, v3, tau, a3, rest)
    for i in range(n):
        v4[i] = qd[i] + h * a3[i]
        x[i] = q[i] + h * v3[i]
    forward_dynamics(kind, p, x, v4, tau, a4, rest)
    sixth = h / 6.0
    for i in range(n):
        q_out[i] = q[i] + sixth * (qd[i] + 2.0 * v2[i] + 2.0 * v3[i] + v4[i])
        qd_out[i] = qd[i] + sixth * (a1[i] + 2.0 * a2[i] + 2.0 * a3[i] + a4[i])


# --------------------------------------------------------------------------- #
# Control laws (Chapter 3)
# --------------------------------------------------------------------------- #
@njit(cache=_CACHE)
def control_torque(  # noqa: ANN201, PLR0913
    ctrl, gains, model, kind, p, q, qd, q_ref, qd_ref, qdd_ref, tau, work
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
    work : ndarray
        Scratch array from :func:`workspace`.

    Notes
    -----
    With ``e = q_d - q`` (Eq. 3.2) and ``s = lambda e + edot``, the SMC of
    Eq. (3.15), written with the thesis's ``e' = q - q_d`` (Eq. 3.5), is
    ``Mhat (qdd_d + lambda edot) + Chat (qd_d + lambda e) + Ghat + Ks sat(s/phi)``
    because ``s' = -s``; the PD-SMC of Eq. (3.44) is
    ``Kp e + Kd edot + Ks sat(s/phi)``; the boundary layer is Eq. (3.45).
    """
    n = q.shape[0]
    e = work[0:n]
    ed = work[3 : 3 + n]
    sat = work[6 : 6 + n]
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
        mass = work[9 : 9 + n * n].reshape((n, n))
        bias = work[18 : 18 + n]
        grav = work[21 : 21 + n]
        qdd_r = work[24 : 24 + n]
        qd_r = work[27 : 27 + n]
        cor = work[30 : 30 + n]
        rest = work[33:]
        robot_terms(kind, p, qm, qdm, mass, bias, rest)
        if model[4] == 0.0:  # motor inertia not part of the estimate
            for i in range(n):
                mass[i, i] -= _motor_inertia(kind, p, i)
        robot_gravity(kind, p, qm, grav, rest)
        for i in range(n):
            qdd_r[i] = qdd_ref[i] + gains[3, i] * ed[i]
            qd_r[i] = qd_ref[i] + gains[3, i] * e[i]
        robot_coriolis_times(kind, p, qm, qdm, qd_r, cor, rest)
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
    work = np.empty(WORK_SIZE)
    for k in range(steps + 1):
        control_torque(
            ctrl, gains, model, model_kind, model_p, q, qd, refs[k, 0], refs[k, 1], refs[k, 2],
            tau, work,
        )
        if k % sample_every == 0:
            j = k // sample_every
            for i in range(n):
                out_q[j, i] = q[i]
                out_qd[j, i] = qd[i]
                out_tau[j, i] = tau[i]
        if k < steps:
            rk4_step(kind, p, q, qd, tau, h, q_next, qd_next, work)
            for i in range(n):
                q[i] = q_next[i]
                qd[i] = qd_next[i]

