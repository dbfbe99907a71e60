"""PD (Eq. 3.4), SMC (Eq. 3.15) and PD-SMC (Eq. 3.44): numpy and compiled forms side by side.

Errors are ``e = q_d - q`` and ``edot = qd_d - qd`` (Eq. 3.2); the sliding
variable is ``s = lambda e + edot`` with the boundary layer of Eq. (3.45),
``sat(s / phi)``. The thesis writes the SMC with ``e' = q - q_d`` (Eq. 3.5);
since ``s' = -s`` the signs below are its Eq. (3.15) rewritten.

The numpy forms are the readable reference (one state, shape ``(n,)``); the
compiled forms (numba, scalar loops, no allocation) are what the simulator
and the nodes run. Tests prove both agree to 1e-12.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ..robots import compiled as robot
from ..robots.base import FloatArray
from .registry import (
    AT_DESIRED,
    KD,
    KP,
    KS,
    LAM,
    PHI,
    S_CORIOLIS,
    S_DAMPING,
    S_GRAVITY,
    S_MASS,
    WITH_MOTOR_INERTIA,
    GainSpec,
    LawEntry,
    LawSetup,
    register_law,
)

PD = 0
SMC = 1
PDSMC = 2
"""Codes of the compiled forms."""

# --------------------------------------------------------------------------- #
# The thesis's gains (Tables 4.16 / 4.33), one spec each
# --------------------------------------------------------------------------- #
GAIN_KP = GainSpec("kp", "proportional gains Kp (Eq. 3.4)", "N m/rad")
GAIN_KD = GainSpec("kd", "derivative gains Kd (Eq. 3.4)", "N m s/rad")
GAIN_KS = GainSpec("ks", "switching gains Ks (Eq. 3.15)", "N m")
GAIN_LAM = GainSpec("lam", "sliding-surface slopes lambda (Eq. 3.13)", "1/s")
GAIN_PHI = GainSpec("phi", "boundary layers phi (Eq. 3.45)", "rad/s", lower_open=True, neutral=1.0)
THESIS_ROWS = (GAIN_KP, GAIN_KD, GAIN_KS, GAIN_LAM, GAIN_PHI)
"""The gain matrix of the three thesis laws (rows ``KP, KD, KS, LAM, PHI``): one layout for
their compiled forms, which share :func:`_errors`; a row a law does not use is neutral."""


# --------------------------------------------------------------------------- #
# Numpy forms
# --------------------------------------------------------------------------- #
def boundary_layer(g: FloatArray, e: FloatArray, ed: FloatArray) -> FloatArray:
    """``sat(s / phi)`` with ``s = lambda e + edot`` (Eq. 3.45)."""
    return np.clip((g[LAM] * e + ed) / g[PHI], -1.0, 1.0)


def pd_torque(setup: LawSetup, q: FloatArray, qd: FloatArray, q_ref: FloatArray, qd_ref: FloatArray,
              qdd_ref: FloatArray) -> FloatArray:  # noqa: ARG001
    """PD, Eq. (3.4): ``Kp e + Kd edot``."""
    g = setup.gains
    return g[KP] * (q_ref - q) + g[KD] * (qd_ref - qd)


def pdsmc_torque(setup: LawSetup, q: FloatArray, qd: FloatArray, q_ref: FloatArray, qd_ref: FloatArray,
                 qdd_ref: FloatArray) -> FloatArray:  # noqa: ARG001
    """PD-SMC, Eq. (3.44): ``Kp e + Kd edot + Ks sat(s / phi)``."""
    g = setup.gains
    e = q_ref - q
    ed = qd_ref - qd
    return g[KP] * e + g[KD] * ed + g[KS] * boundary_layer(g, e, ed)


def smc_torque(setup: LawSetup, q: FloatArray, qd: FloatArray, q_ref: FloatArray, qd_ref: FloatArray,
               qdd_ref: FloatArray) -> FloatArray:
    """SMC, Eq. (3.15): ``Mhat (qdd_d + lambda edot) + Chat (qd_d + lambda e) + Ghat
    + s_B B (qd_d + lambda e) + Ks sat(s / phi)``.

    ``Mhat = s_M Mbar`` (``s_M M`` without the motor inertia), ``Chat = s_C C``,
    ``Ghat = s_G G`` of the nominal model, evaluated at the measured state (or at
    the desired one); the scales are :attr:`LawSetup.smc_model`.
    """
    g, m, robot_model = setup.gains, setup.smc_model, setup.model
    e = q_ref - q
    ed = qd_ref - qd
    qm, qdm = (q_ref, qd_ref) if m[AT_DESIRED] != 0.0 else (q, qd)
    mass = robot_model.mass_matrix(qm)
    if m[WITH_MOTOR_INERTIA] == 0.0:
        mass = mass - np.diag(robot_model.J)
    qdd_r = qdd_ref + g[LAM] * ed
    qd_r = qd_ref + g[LAM] * e
    return (m[S_MASS] * mass @ qdd_r + m[S_CORIOLIS] * robot_model.coriolis_matrix(qm, qdm) @ qd_r
            + m[S_GRAVITY] * robot_model.gravity(qm) + m[S_DAMPING] * robot_model.B * qd_r
            + g[KS] * boundary_layer(g, e, ed))


# --------------------------------------------------------------------------- #
# Linear gains inside the boundary layer (the discrete stability check)
# --------------------------------------------------------------------------- #
def _ks_over_phi(g: FloatArray) -> FloatArray:
    return np.diag(g[KS]) @ np.linalg.solve(np.diag(g[PHI]), np.eye(g.shape[1]))


def pd_linear_gains(g: FloatArray, smc_model: FloatArray, mass: FloatArray) -> tuple[FloatArray, FloatArray]:  # noqa: ARG001
    return np.diag(g[KP]), np.diag(g[KD])


def pdsmc_linear_gains(g: FloatArray, smc_model: FloatArray, mass: FloatArray) -> tuple[FloatArray, FloatArray]:  # noqa: ARG001
    ks_phi = _ks_over_phi(g)
    return np.diag(g[KP]) + ks_phi @ np.diag(g[LAM]), np.diag(g[KD]) + ks_phi


def smc_linear_gains(g: FloatArray, smc_model: FloatArray, mass: FloatArray) -> tuple[FloatArray, FloatArray]:
    ks_phi = _ks_over_phi(g)
    lam = np.diag(g[LAM])
    return ks_phi @ lam, float(smc_model[S_MASS]) * mass @ lam + ks_phi


# --------------------------------------------------------------------------- #
# Compiled forms (one state; scratch from ``work``)
# --------------------------------------------------------------------------- #
@njit(cache=True, inline="always")
def _errors(g, q, qd, q_ref, qd_ref, e, ed, sat, n):  # noqa: ANN001, ANN202, PLR0913
    """``e``, ``edot`` (Eq. 3.2) and ``sat(s / phi)`` (Eq. 3.45)."""
    for i in range(n):
        e[i] = q_ref[i] - q[i]
        ed[i] = qd_ref[i] - qd[i]
        s = (g[LAM, i] * e[i] + ed[i]) / g[PHI, i]
        if s > 1.0:
            s = 1.0
        elif s < -1.0:
            s = -1.0
        sat[i] = s


@njit(cache=True, inline="always")
def _pd(g, e, ed, tau, n):  # noqa: ANN001, ANN202
    for i in range(n):
        tau[i] = g[KP, i] * e[i] + g[KD, i] * ed[i]


@njit(cache=True, inline="always")
def _pdsmc(g, e, ed, sat, tau, n):  # noqa: ANN001, ANN202
    for i in range(n):
        tau[i] = g[KP, i] * e[i] + g[KD, i] * ed[i] + g[KS, i] * sat[i]


@njit(cache=True)
def _smc(g, m, kind, p, q, qd, q_ref, qd_ref, qdd_ref, e, ed, sat, tau, work):  # noqa: ANN001, ANN202, PLR0913
    n = q.shape[0]
    qm = q
    qdm = qd
    if m[AT_DESIRED] != 0.0:
        qm = q_ref
        qdm = qd_ref
    bias = work[0:n]
    grav = work[n : 2 * n]
    qdd_r = work[2 * n : 3 * n]
    qd_r = work[3 * n : 4 * n]
    cor = work[4 * n : 5 * n]
    mass = work[5 * n : 5 * n + n * n].reshape((n, n))
    rest = work[5 * n + n * n :]
    robot.terms(kind, p, qm, qdm, mass, bias, rest)
    if m[WITH_MOTOR_INERTIA] == 0.0:
        for i in range(n):
            mass[i, i] -= robot.motor_inertia(kind, p, i)
    robot.gravity(kind, p, qm, grav, rest)
    for i in range(n):
        qdd_r[i] = qdd_ref[i] + g[LAM, i] * ed[i]
        qd_r[i] = qd_ref[i] + g[LAM, i] * e[i]
    robot.coriolis_times(kind, p, qm, qdm, qd_r, cor, rest)
    for i in range(n):
        acc = 0.0
        for j in range(n):
            acc += mass[i, j] * qdd_r[j]
        tau[i] = (
            m[S_MASS] * acc
            + m[S_CORIOLIS] * cor[i]
            + m[S_GRAVITY] * grav[i]
            + m[S_DAMPING] * robot.damping(kind, p, i) * qd_r[i]
            + g[KS, i] * sat[i]
        )


@njit(cache=True, inline="always")
def law_torque(code, gains, smc_model, kind, p, q, qd, q_ref, qd_ref, qdd_ref, tau, work, n):  # noqa: ANN001, ANN201, PLR0913
    """:func:`compiled_torque` with its inputs as separate vectors of ``n`` joints.

    What a compiled loop calls: ``n`` is its constant joint count (loops of known length)
    and the reference rows are views of its samples (nothing copied).
    """
    e = work[0:n]
    ed = work[n : 2 * n]
    sat = work[2 * n : 3 * n]
    _errors(gains, q, qd, q_ref, qd_ref, e, ed, sat, n)
    if code == PD:
        _pd(gains, e, ed, tau, n)
    elif code == PDSMC:
        _pdsmc(gains, e, ed, sat, tau, n)
    elif code == SMC:
        _smc(gains, smc_model, kind, p, q, qd, q_ref, qd_ref, qdd_ref, e, ed, sat, tau, work[3 * n :])


@njit(cache=True)
def compiled_torque(code, gains, smc_model, kind, p, x, tau, work):  # noqa: ANN001, ANN201
    """The law ``code`` (``PD``, ``SMC``, ``PDSMC``) for one state, into ``tau``.

    ``x`` holds the inputs one after the other, ``q, qd, q_d, qd_d, qdd_d`` (``5 n`` floats:
    from Python each argument of a compiled call costs about 0.1 us, and one array built from
    a flat list about half what five arrays or one built from nested tuples cost).
    ``gains`` is :attr:`LawSetup.gains`, ``smc_model`` :attr:`LawSetup.smc_model`,
    ``(kind, p)`` the nominal robot's compiled form
    (:func:`pdsmc_ros.robots.compiled.pack`), ``work`` from
    :func:`pdsmc_ros.robots.compiled.workspace`.
    """
    n = tau.shape[0]
    law_torque(code, gains, smc_model, kind, p, x[0:n], x[n : 2 * n], x[2 * n : 3 * n], x[3 * n : 4 * n],
               x[4 * n : 5 * n], tau, work, n)


register_law(LawEntry("pd", "PD", (GAIN_KP, GAIN_KD), pd_torque, "Eq. (3.4)", PD, pd_linear_gains,
                      rows=THESIS_ROWS))
register_law(LawEntry("smc", "SMC", (GAIN_KS, GAIN_LAM, GAIN_PHI), smc_torque, "Eq. (3.15)", SMC,
                      smc_linear_gains, rows=THESIS_ROWS, model_based=True))
register_law(LawEntry("pdsmc", "PD-SMC", THESIS_ROWS, pdsmc_torque, "Eq. (3.44)", PDSMC, pdsmc_linear_gains,
                      rows=THESIS_ROWS))
