"""The thesis laws read in numpy, straight from their equations: the oracle the compiled laws
(the package's one form of each) are held against, and a law written in Python for the tests."""

from __future__ import annotations

import numpy as np

from pdsmc_ros.control.registry import (
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
    LawSetup,
)
from pdsmc_ros.robots.base import FloatArray


def boundary_layer(g: FloatArray, e: FloatArray, ed: FloatArray) -> FloatArray:
    """``sat(s / phi)`` with ``s = lambda e + edot`` (Eq. 3.45)."""
    return np.clip((g[LAM] * e + ed) / g[PHI], -1.0, 1.0)


def pdsmc_reading(setup: LawSetup, q: FloatArray, qd: FloatArray, q_ref: FloatArray, qd_ref: FloatArray,
                  qdd_ref: FloatArray) -> FloatArray:  # noqa: ARG001
    """PD-SMC, Eq. (3.44): ``Kp e + Kd edot + Ks sat(s / phi)``."""
    g = setup.gains
    e = q_ref - q
    ed = qd_ref - qd
    return g[KP] * e + g[KD] * ed + g[KS] * boundary_layer(g, e, ed)


def smc_reading(setup: LawSetup, q: FloatArray, qd: FloatArray, q_ref: FloatArray, qd_ref: FloatArray,
                qdd_ref: FloatArray) -> FloatArray:
    """SMC, Eq. (3.15): ``Mhat (qdd_d + lambda edot) + Chat (qd_d + lambda e) + Ghat
    + s_B B (qd_d + lambda e) + Ks sat(s / phi)``, the model at the measured (or desired) state."""
    g, m, model = setup.gains, setup.smc_model, setup.model
    e = q_ref - q
    ed = qd_ref - qd
    qm, qdm = (q_ref, qd_ref) if m[AT_DESIRED] != 0.0 else (q, qd)
    mass = model.mass_matrix(qm)
    if m[WITH_MOTOR_INERTIA] == 0.0:
        mass = mass - np.diag(model.J)
    qdd_r = qdd_ref + g[LAM] * ed
    qd_r = qd_ref + g[LAM] * e
    return (m[S_MASS] * mass @ qdd_r + m[S_CORIOLIS] * model.coriolis_matrix(qm, qdm) @ qd_r
            + m[S_GRAVITY] * model.gravity(qm) + m[S_DAMPING] * model.B * qd_r
            + g[KS] * boundary_layer(g, e, ed))

