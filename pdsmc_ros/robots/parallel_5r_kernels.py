"""The five-bar's compiled form (numba): one state, scratch from ``work``.

The same mathematics as :class:`pdsmc_ros.robots.parallel_5r.Parallel5R`
(the reduced model, Appendix Eqs. 47-70) written as scalar loops; tests prove
both agree to 1e-12.
"""

from __future__ import annotations

import math

from numba import njit

from ..kernels.options import ALLOCATION_FREE
from .kernel_math import entry_at

PARALLEL_5R = 1
"""Code of the compiled form (:mod:`pdsmc_ros.robots.compiled`)."""
N = 2
"""Actuated joints: a constant, so the compiled loops have known lengths."""

# The flat parameter array of :meth:`Parallel5R.pack`, by name: each chain is
# ``W(4) w(2) I(2) lengths(2)``
_LEFT = 0  # links 1 and 3
_L1 = 8
_L3 = 9
_RIGHT = 10  # links 2 and 4
_L2 = 18
_L4 = 19
_L5 = 20  # the base
_J = 21
_B = 23
_G = 25
_MODE = 26  # assembly mode, +1 or -1

GEOMETRY_SIZE = 24
_TRIG = 16
"""Where :func:`_geometry` puts ``cos, sin`` of the left chain's links, then the right's."""



@njit(cache=True, inline="always")
def _geometry(p, q, qd, geo):  # noqa: ANN001, ANN202
    """Open-tree angles/rates and ``R = d(q3, q4)/d(q1, q2)`` into ``geo``.

    ``geo`` (:data:`GEOMETRY_SIZE` floats) receives ``ql = (q1, q3)`` [0:2], ``qr = (q2, q4)``
    [2:4], their rates ``qdl`` [4:6] and ``qdr`` [6:8], ``rho`` [8:12]
    (row-major 2x2, rows q3, q4), ``A_pas^{-1}`` [12:16] (row-major 2x2) and the cosine and
    sine of each link's absolute angle [16:24] (:data:`_TRIG`).

    The chains' terms and ``Jdot`` read those instead of taking their own: the same angles, formed
    the same way, so the same floats, once per evaluation. The compiler cannot see that itself in
    the production loop, whose states live in arrays that may share memory with ``geo``.
    """
    l1 = p[_L1]
    l3 = p[_L3]
    l2 = p[_L2]
    l4 = p[_L4]
    l5 = p[_L5]
    mode = p[_MODE]
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
    # the links' absolute angles as the chains form them (q1 + (th13 - q1) need not be th13's float)
    left = geo[0] + geo[1]
    right = geo[2] + geo[3]
    geo[_TRIG] = c1
    geo[_TRIG + 1] = s1
    geo[_TRIG + 2] = math.cos(left)
    geo[_TRIG + 3] = math.sin(left)
    geo[_TRIG + 4] = c2
    geo[_TRIG + 5] = s2
    geo[_TRIG + 6] = math.cos(right)
    geo[_TRIG + 7] = math.sin(right)
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
    _rates(geo, qd[0], qd[1])


@njit(cache=True, inline="always")
def _rates(geo, w0, w1):  # noqa: ANN001, ANN202
    """The open tree's rates ``qdl``, ``qdr`` (``geo[4:8]``) at actuated rates ``(w0, w1)``, from
    ``rho`` (``geo[8:12]``): positions fix the rest of :func:`_geometry`, so one geometry serves
    several rates (:func:`model_terms`)."""
    geo[4] = w0
    geo[5] = geo[8] * w0 + geo[9] * w1
    geo[6] = w1
    geo[7] = geo[10] * w0 + geo[11] * w1


@njit(cache=True, inline="always")
def _chain_jdot_times(la, lb, ca, sa, cab, sab, w_a, w_ab, v0, v1):  # noqa: ANN001, ANN202, PLR0913
    """``Jdot v`` of a 2-link chain (lengths ``la``, ``lb``; cosines, sines and rates of its links'
    absolute angles), ``Jdot = [[-la ca wa - lb cab wab, -lb cab wab], [-la sa wa - lb sab wab, -lb sab wab]]``."""
    x = (-la * ca * w_a - lb * cab * w_ab) * v0 - lb * cab * w_ab * v1
    y = (-la * sa * w_a - lb * sab * w_ab) * v0 - lb * sab * w_ab * v1
    return x, y


@njit(cache=True, inline="always")
def _jdot_times(p, geo, vl0, vl1, vr0, vr1):  # noqa: ANN001, ANN202
    """``Jdot_left vl - Jdot_right vr`` (rates of the constraint), as two floats."""
    t = _TRIG
    lx, ly = _chain_jdot_times(p[_L1], p[_L3], geo[t], geo[t + 1], geo[t + 2], geo[t + 3], geo[4], geo[4] + geo[5],
                               vl0, vl1)
    rx, ry = _chain_jdot_times(p[_L2], p[_L4], geo[t + 4], geo[t + 5], geo[t + 6], geo[t + 7], geo[6],
                               geo[6] + geo[7], vr0, vr1)
    return lx - rx, ly - ry


@njit(cache=True, inline="always")
def _chain(p, base, g, geo, trig, d0, d1):  # noqa: ANN001, ANN202, PLR0913
    """One open 2-link chain (parameters from ``p[base]``, layout ``W(4) w(2) I(2)``) with the
    cosines and sines of its links' absolute angles at ``geo[trig:trig + 4]`` (:func:`_geometry`)
    and relative rates ``d``: its mass matrix ``(k00, k01, k11)`` and ``C' qd' + G'`` ``(b0, b1)``.

    :class:`pdsmc_ros.robots.chain.PlanarChain`'s terms written out for two links,
    in scalars so a closed loop keeps them in registers.
    """
    e0 = d0
    e1 = e0 + d1
    c0 = geo[trig]
    s0 = geo[trig + 1]
    c1 = geo[trig + 2]
    s1 = geo[trig + 3]
    w00 = p[base]
    w01 = p[base + 1]
    w10 = p[base + 2]
    w11 = p[base + 3]
    m00 = w00 * (c0 * c0 + s0 * s0) + p[base + 6]
    m01 = w01 * (c0 * c1 + s0 * s1)
    m10 = w10 * (c1 * c0 + s1 * s0)
    m11 = w11 * (c1 * c1 + s1 * s1) + p[base + 7]
    y0 = g * p[base + 4] * c0
    y0 += w00 * (s0 * c0 - c0 * s0) * e0 * e0
    y0 += w01 * (s0 * c1 - c0 * s1) * e1 * e1
    y1 = g * p[base + 5] * c1
    y1 += w10 * (s1 * c0 - c1 * s0) * e0 * e0
    y1 += w11 * (s1 * c1 - c1 * s1) * e1 * e1
    return 0.0 + m00 + m01 + m10 + m11, 0.0 + m01 + m11, 0.0 + m11, 0.0 + y0 + y1, 0.0 + y1


@njit(cache=True, inline="always")
def _passive_rates(geo, cdot0, cdot1):  # noqa: ANN001, ANN202
    """``rhodot qd`` for (q3, q4) from the constraint rates: ``-A_pas^{-1} cdot``."""
    pas0 = -(geo[12] * cdot0 + geo[13] * cdot1)
    pas1 = -(geo[14] * cdot0 + geo[15] * cdot1)
    return pas0, pas1


@njit(cache=True, inline="always")
def _terms(p, geo):  # noqa: ANN001, ANN202
    """Reduced ``Mbar`` ``(m00, m01, m11)`` and ``C qd + G`` ``(b0, b1)`` at ``geo`` (:func:`_geometry`)."""
    l00, l01, l11, lb0, lb1 = _chain(p, _LEFT, p[_G], geo, _TRIG, geo[4], geo[5])
    q00, q01, q11, qb0, qb1 = _chain(p, _RIGHT, p[_G], geo, _TRIG + 4, geo[6], geo[7])
    cdot0, cdot1 = _jdot_times(p, geo, geo[4], geo[5], geo[6], geo[7])
    pas0, pas1 = _passive_rates(geo, cdot0, cdot1)
    # f = C' qd' + M' rhodot qd + G' per chain
    fl0 = lb0 + l01 * pas0
    fl1 = lb1 + l11 * pas0
    fr0 = qb0 + q01 * pas1
    fr1 = qb1 + q11 * pas1
    # rho_left = [[1, 0], [r00, r01]], rho_right = [[0, 1], [r10, r11]]
    r00 = geo[8]
    r01 = geo[9]
    r10 = geo[10]
    r11 = geo[11]
    b0 = fl0 + r00 * fl1 + r10 * fr1
    b1 = r01 * fl1 + fr0 + r11 * fr1
    # rho^T M rho for each chain
    m00 = l00 + 2.0 * r00 * l01 + r00 * r00 * l11
    m01 = r01 * l01 + r00 * r01 * l11
    m11 = r01 * r01 * l11
    m00 += r10 * r10 * q11
    m01 += r10 * q01 + r10 * r11 * q11
    m11 += q00 + 2.0 * r11 * q01 + r11 * r11 * q11
    return m00 + p[_J], m01, m11 + p[_J + 1], b0, b1


@njit(cache=True, inline="always")
def _solve(m00, m01, m11, r0, r1):  # noqa: ANN001, ANN202
    """``Mbar x = r`` for the symmetric 2 x 2 of :func:`_terms` (Cholesky in scalars): ``x`` as two floats."""
    c00 = math.sqrt(m00)
    c10 = m01 / c00
    c11 = math.sqrt(m11 - c10 * c10)
    z0 = r0 / c00
    z1 = (r1 - c10 * z0) / c11
    x1 = z1 / c11
    x0 = (z0 - c10 * x1) / c00
    return x0, x1


@njit(**ALLOCATION_FREE)
def terms(p, q, qd, mass, bias, work):  # noqa: ANN001, ANN202
    """Reduced ``Mbar`` and ``C qd + G`` of the five-bar."""
    geo = work[0:GEOMETRY_SIZE]
    _geometry(p, q, qd, geo)
    m00, m01, m11, b0, b1 = _terms(p, geo)
    _put_mass(mass, m00, m01, m11)
    bias[0] = b0
    bias[1] = b1


@njit(cache=True, inline="always")
def _put_mass(mass, m00, m01, m11):  # noqa: ANN001, ANN202
    """The symmetric 2 x 2 ``Mbar`` of :func:`_terms` into ``mass``."""
    mass[0, 0] = m00
    mass[0, 1] = m01
    mass[1, 0] = m01
    mass[1, 1] = m11


@njit(cache=True, inline="always")
def accelerations(p, q, qd, tau, out, work):  # noqa: ANN001, ANN202
    """Eq. (4.1) for the reduced model, ``qdd = Mbar^{-1} (tau - C qd - B qd - G)``, into ``out``."""
    _geometry(p, q, qd, work)  # its GEOMETRY_SIZE floats at the front of work (no slice: the hot path)
    m00, m01, m11, b0, b1 = _terms(p, work)
    out[0], out[1] = _solve(m00, m01, m11, tau[0] - b0 - p[_B] * qd[0], tau[1] - b1 - p[_B + 1] * qd[1])


@njit(**ALLOCATION_FREE)
def coriolis_times(p, q, qd, v, out, work):  # noqa: ANN001, ANN202
    """``C(q, qd) v`` of the reduced model, ``C = rho^T C' rho + rho^T M' rhodot``."""
    geo = work[0:GEOMETRY_SIZE]
    _geometry(p, q, qd, geo)
    _coriolis_at(p, geo, v, out)


@njit(**ALLOCATION_FREE)
def model_terms(p, q, qd, v, mass, grav, cor, work):  # noqa: ANN001, ANN202, PLR0913
    """``Mbar(q)``, ``G(q)`` and ``C(q, qd) v`` from one :func:`_geometry`: what a model-based law needs
    at every step (:func:`pdsmc_ros.control.laws.model_part`), the very floats of :func:`terms`,
    :func:`gravity` and :func:`coriolis_times` called apart (test/robots: bit for bit), which solve
    the loop closure three times."""
    geo = work[0:GEOMETRY_SIZE]
    _geometry(p, q, qd, geo)
    m00, m01, m11, _, _ = _terms(p, geo)
    _put_mass(mass, m00, m01, m11)
    _coriolis_at(p, geo, v, cor)
    _rates(geo, 0.0, 0.0)  # gravity: C qd + G at rest
    _, _, _, g0, g1 = _terms(p, geo)
    grav[0] = g0
    grav[1] = g1


@njit(cache=True, inline="always")
def _chain_coriolis_times(p, base, geo, trig, d0, d1, v0, v1):  # noqa: ANN001, ANN202, PLR0913
    """``C'(q', qd') v`` of one open 2-link chain (``W`` from ``p[base]``), cosines and sines of its links at
    ``geo[trig:trig + 4]``, relative rates ``d`` and ``v``: :func:`~pdsmc_ros.robots.chain.chain_coriolis_times`
    written out for two links in the same order of operations, as two floats (its sums start from 0.0 as
    its loops do: the very floats, but for the sign of a link angle that is exactly -0.0)."""
    c0 = geo[trig]
    s0 = geo[trig + 1]
    c1 = geo[trig + 2]
    s1 = geo[trig + 3]
    thd0 = 0.0 + d0
    thd1 = thd0 + d1
    thv0 = 0.0 + v0
    thv1 = thv0 + v1
    y0 = 0.0 + p[base] * (s0 * c0 - c0 * s0) * thd0 * thv0
    y0 += p[base + 1] * (s0 * c1 - c0 * s1) * thd1 * thv1
    y1 = 0.0 + p[base + 2] * (s1 * c0 - c1 * s0) * thd0 * thv0
    y1 += p[base + 3] * (s1 * c1 - c1 * s1) * thd1 * thv1
    return 0.0 + y0 + y1, 0.0 + y1


@njit(cache=True, inline="always")
def _coriolis_at(p, geo, v, out):  # noqa: ANN001, ANN202
    """:func:`coriolis_times` at a computed geometry, in scalars (no scratch)."""
    vl0 = v[0]
    vl1 = geo[8] * v[0] + geo[9] * v[1]
    vr0 = v[1]
    vr1 = geo[10] * v[0] + geo[11] * v[1]
    cl0, cl1 = _chain_coriolis_times(p, _LEFT, geo, _TRIG, geo[4], geo[5], vl0, vl1)
    cr0, cr1 = _chain_coriolis_times(p, _RIGHT, geo, _TRIG + 4, geo[6], geo[7], vr0, vr1)
    cdot0, cdot1 = _jdot_times(p, geo, vl0, vl1, vr0, vr1)
    pas0, pas1 = _passive_rates(geo, cdot0, cdot1)
    _, l01, l11, _, _ = _chain(p, _LEFT, 0.0, geo, _TRIG, geo[4], geo[5])
    _, q01, q11, _, _ = _chain(p, _RIGHT, 0.0, geo, _TRIG + 4, geo[6], geo[7])
    fl0 = cl0 + l01 * pas0
    fl1 = cl1 + l11 * pas0
    fr0 = cr0 + q01 * pas1
    fr1 = cr1 + q11 * pas1
    out[0] = fl0 + geo[8] * fl1 + geo[10] * fr1
    out[1] = geo[9] * fl1 + fr0 + geo[11] * fr1


@njit(**ALLOCATION_FREE)
def gravity(p, q, out, work):  # noqa: ANN001, ANN202
    mass = work[0:4].reshape((2, 2))
    qd = work[4:6]
    qd[0] = 0.0
    qd[1] = 0.0
    terms(p, q, qd, mass, out, work[6:])


motor_inertia = entry_at(_J)
"""Motor inertia ``J_i``: ``(p, i) -> float``."""
damping = entry_at(_B)
"""Motor viscous damping ``B_i``: ``(p, i) -> float``."""


@njit(**ALLOCATION_FREE)
def outputs(p, q, qd, out, work):  # noqa: ANN001, ANN201
    """End-effector ``(x, y)`` (Appendix Eqs. 26-34) into ``out[0:2]``, the passive joints
    ``(q3, q4)`` wrapped to (-pi, pi] into ``out[2:4]`` and their rates (``rho qd``) into
    ``out[4:6]``."""
    geo = work[0:GEOMETRY_SIZE]
    _geometry(p, q, qd, geo)
    out[0] = p[_L1] * geo[_TRIG] + p[_L3] * geo[_TRIG + 2]
    out[1] = p[_L1] * geo[_TRIG + 1] + p[_L3] * geo[_TRIG + 3]
    for i in range(2):
        angle = geo[1 + 2 * i]
        out[2 + i] = math.pi - (math.pi - angle) % (2.0 * math.pi)
        out[4 + i] = geo[5 + 2 * i]


# --------------------------------------------------------------------------- #
# Over a batch of states: what the numpy interface (Parallel5R) calls
# --------------------------------------------------------------------------- #
@njit(**ALLOCATION_FREE)
def batch_terms(p, q, qd, mass, bias, work):  # noqa: ANN001, ANN201
    """:func:`terms` at each row of ``q``, ``qd`` (shape ``(k, 2)``): ``mass`` ``(k, 2, 2)``, ``bias`` ``(k, 2)``."""
    for i in range(q.shape[0]):
        terms(p, q[i], qd[i], mass[i], bias[i], work)


@njit(**ALLOCATION_FREE)
def batch_coriolis_matrix(p, q, qd, out, work):  # noqa: ANN001, ANN201
    """``C(q, qd)`` at each row (``out`` ``(k, 2, 2)``), column ``j`` from :func:`coriolis_times` of the unit vector."""
    v = work[-4:-2]
    col = work[-2:]
    for i in range(q.shape[0]):
        for j in range(N):
            v[0] = 0.0
            v[1] = 0.0
            v[j] = 1.0
            coriolis_times(p, q[i], qd[i], v, col, work)
            out[i, 0, j] = col[0]
            out[i, 1, j] = col[1]
