"""PD (Eq. 3.4), SMC (Eq. 3.15) and PD-SMC (Eq. 3.44), written once, compiled.

Errors are ``e = q_d - q`` and ``edot = qd_d - qd`` (Eq. 3.2); the sliding
variable is ``s = lambda e + edot`` with the boundary layer of Eq. (3.45),
``sat(s / phi)``. The thesis writes the SMC with ``e' = q - q_d`` (Eq. 3.5);
since ``s' = -s`` the signs below are its Eq. (3.15) rewritten.

Each law is one compiled function (numba, scalar loops, no allocation), callable from Python
too; the simulator, the nodes and every robot run it through
:func:`pdsmc_ros.control.law.law_torque`. The tests hold it against the equations read
in numpy (test/control/test_laws.py). :func:`model_part` (the SMC's model terms) is shared
with the model-based laws of :mod:`.baselines` and :mod:`.sliding`.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ..kernels.options import ALLOCATION_FREE
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
)

PD = 0
SMC = 1
PDSMC = 2
"""Codes of the compiled forms (:func:`pdsmc_ros.control.law.law_torque`)."""

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
def joint_errors(g, q, qd, q_ref, qd_ref, i):  # noqa: ANN001, ANN201, PLR0913
    """Joint ``i``'s ``e``, ``edot`` (Eq. 3.2) and ``sat(s / phi)`` (Eq. 3.45) of the thesis laws' gain
    matrix, as three floats.

    The thesis laws are written per joint, in scalars: the loop that calls them keeps them in
    registers (through scratch arrays they cost the serial arm's closed loop about 4 %,
    docs/PERFORMANCE.md).
    """
    e = q_ref[i] - q[i]
    ed = qd_ref[i] - qd[i]
    s = (g[LAM, i] * e + ed) / g[PHI, i]
    if s > 1.0:
        s = 1.0
    elif s < -1.0:
        s = -1.0
    return e, ed, s


@njit(cache=True, inline="always")
def errors(g, q, qd, q_ref, qd_ref, e, ed, sat, n):  # noqa: ANN001, ANN201, PLR0913
    """:func:`joint_errors` of every joint, into ``e``, ``edot`` and ``sat`` (the laws that need them as arrays)."""
    for i in range(n):
        e[i], ed[i], sat[i] = joint_errors(g, q, qd, q_ref, qd_ref, i)


@njit(cache=True, inline="always")
def pd(g, e, ed, i):  # noqa: ANN001, ANN201
    """PD, Eq. (3.4): joint ``i``'s torque."""
    return g[KP, i] * e + g[KD, i] * ed


@njit(cache=True, inline="always")
def pdsmc(g, e, ed, sat, i):  # noqa: ANN001, ANN201
    """PD-SMC, Eq. (3.44): joint ``i``'s torque."""
    return g[KP, i] * e + g[KD, i] * ed + g[KS, i] * sat


@njit(**ALLOCATION_FREE)
def model_part(m, kind, p, q, qd, q_ref, qd_ref, a, v, tau, work):  # noqa: ANN001, ANN201, PLR0913
    """The model estimate's torque, ``Mhat a + Chat v + Ghat + s_B B v``, into ``tau`` (Eq. 3.15's model terms).

    ``Mhat = s_M Mbar`` (``s_M M`` without the motor inertia), ``Chat = s_C C``, ``Ghat = s_G G``
    of the nominal robot ``(kind, p)`` at the measured state, or at the desired one
    (``m`` is :attr:`LawSetup.smc_model`); ``a`` and ``v`` are the law's: the SMC's
    ``qdd_r`` and ``qd_r``, the computed torque's commanded acceleration and the velocity.
    ``work`` holds ``2 n + n^2`` floats and the robot's scratch.
    """
    n = q.shape[0]
    qm = q
    qdm = qd
    if m[AT_DESIRED] != 0.0:
        qm = q_ref
        qdm = qd_ref
    grav = work[0:n]
    cor = work[n : 2 * n]
    mass = work[2 * n : 2 * n + n * n].reshape((n, n))
    robot.model_terms(kind, p, qm, qdm, v, mass, grav, cor, work[2 * n + n * n :])
    if m[WITH_MOTOR_INERTIA] == 0.0:
        for i in range(n):
            mass[i, i] -= robot.motor_inertia(kind, p, i)
    for i in range(n):
        acc = 0.0
        for j in range(n):
            acc += mass[i, j] * a[j]
        tau[i] = (
            m[S_MASS] * acc
            + m[S_CORIOLIS] * cor[i]
            + m[S_GRAVITY] * grav[i]
            + m[S_DAMPING] * robot.damping(kind, p, i) * v[i]
        )


@njit(**ALLOCATION_FREE)
def smc(g, m, kind, p, q, qd, q_ref, qd_ref, qdd_ref, e, ed, sat, tau, work):  # noqa: ANN001, ANN201, PLR0913
    """SMC, Eq. (3.15): the model part with ``qdd_r = qdd_d + lambda edot``, ``qd_r = qd_d + lambda e``,
    plus ``Ks sat(s / phi)`` (added last: the same roundings as the equation's sum in its order)."""
    n = q.shape[0]
    qdd_r = work[0:n]
    qd_r = work[n : 2 * n]
    for i in range(n):
        qdd_r[i] = qdd_ref[i] + g[LAM, i] * ed[i]
        qd_r[i] = qd_ref[i] + g[LAM, i] * e[i]
    model_part(m, kind, p, q, qd, q_ref, qd_ref, qdd_r, qd_r, tau, work[2 * n :])
    for i in range(n):
        tau[i] += g[KS, i] * sat[i]


PD_LAW = LawEntry("pd", "PD", (GAIN_KP, GAIN_KD), equation="Eq. (3.4)", code=PD,
                  linear_gains=pd_linear_gains, rows=THESIS_ROWS)
SMC_LAW = LawEntry("smc", "SMC", (GAIN_KS, GAIN_LAM, GAIN_PHI), equation="Eq. (3.15)", code=SMC,
                   linear_gains=smc_linear_gains, rows=THESIS_ROWS, model_based=True)
PDSMC_LAW = LawEntry("pdsmc", "PD-SMC", THESIS_ROWS, equation="Eq. (3.44)", code=PDSMC,
                     linear_gains=pdsmc_linear_gains, rows=THESIS_ROWS)
