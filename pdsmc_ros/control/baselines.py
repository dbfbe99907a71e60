"""The model-based baselines beside the thesis's laws: PD with gravity compensation and computed torque.

Written once, compiled (:func:`pdsmc_ros.control.law.law_torque` calls them). Errors
are the thesis's, ``e = q_d - q``, ``edot = qd_d - qd`` (Eq. 3.2). The model estimate is the
SMC's (:attr:`LawSetup.smc_model`: ``Mhat = s_M Mbar``, ``Chat = s_C C``, ``Ghat = s_G G``,
``Bhat = s_B B`` of the nominal robot; ``--smc-reading``), so the three model-based laws
compare on the same knowledge of the arm.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from numba import njit

from ..kernels.options import ALLOCATION_FREE
from ..robots import compiled as robot
from ..robots.base import FloatArray, Manipulator
from .laws import GAIN_KD, GAIN_KP, THESIS_ROWS, model_part, pd_linear_gains
from .registry import AT_DESIRED, KD, KP, S_GRAVITY, S_MASS, GainSpec, LawEntry

PDG = 3
CTC = 4
"""Codes of the compiled forms."""

GAIN_OMEGA = GainSpec("omega_n", "natural frequencies omega_n of the computed torque's error dynamics "
                      "(Kp = omega_n^2)", "rad/s", lower_open=True, neutral=1.0)
GAIN_ZETA = GainSpec("zeta", "damping ratios zeta of the computed torque's error dynamics (Kd = 2 zeta omega_n)",
                     "1", lower_open=True, neutral=1.0)
CTC_ROWS = (GAIN_OMEGA, GAIN_ZETA)
OMEGA, ZETA = range(2)


@njit(**ALLOCATION_FREE)
def pdg(g, m, kind, p, q, q_ref, e, ed, tau, work):  # noqa: ANN001, ANN201, PLR0913
    """PD with gravity compensation: ``tau = Kp e + Kd edot + Ghat(q)``.

    The PD of Eq. (3.4) plus the model estimate's gravity ``s_G G(q)`` (at the desired ``q_d``
    when the estimate is read at the desired state). Takegaki and Arimoto's PD plus gravity
    (Takegaki & Arimoto 1981, "A new feedback method for dynamic control of manipulators",
    J. Dyn. Syst. Meas. Control 103(2)): with the exact gravity, globally asymptotically stable
    at a constant set point for any positive Kp, Kd. Gain rows are the thesis laws' (``kp, kd``).
    """
    n = q.shape[0]
    qm = q_ref if m[AT_DESIRED] != 0.0 else q
    grav = work[0:n]
    robot.gravity(kind, p, qm, grav, work[n:])
    for i in range(n):
        tau[i] = g[KP, i] * e[i] + g[KD, i] * ed[i] + m[S_GRAVITY] * grav[i]


@njit(**ALLOCATION_FREE)
def ctc(g, m, kind, p, q, qd, q_ref, qd_ref, qdd_ref, tau, work):  # noqa: ANN001, ANN201, PLR0913
    """Computed torque: ``tau = Mhat(q) (qdd_d + Kd edot + Kp e) + Chat(q, qd) qd + Ghat(q) + Bhat qd``.

    ``Kp = omega_n^2``, ``Kd = 2 zeta omega_n`` per joint (Spong, Hutchinson & Vidyasagar 2006,
    "Robot Modeling and Control", Section 8.3, inverse dynamics / computed torque; Craig 2005,
    "Introduction to Robotics", Section 10.5). With the exact model (``s_M = s_C = s_G = s_B = 1``)
    each joint's error obeys ``edd + 2 zeta omega_n edot + omega_n^2 e = 0``. Read at the desired
    state, the model terms are ``Mhat(q_d)``, ``Chat(q_d, qd_d) qd_d``, ``Ghat(q_d)``, ``Bhat qd_d``.
    """
    n = q.shape[0]
    a = work[0:n]
    v = work[n : 2 * n]
    desired = m[AT_DESIRED] != 0.0
    for i in range(n):
        w = g[OMEGA, i]
        a[i] = qdd_ref[i] + 2.0 * g[ZETA, i] * w * (qd_ref[i] - qd[i]) + w * w * (q_ref[i] - q[i])
        v[i] = qd_ref[i] if desired else qd[i]
    model_part(m, kind, p, q, qd, q_ref, qd_ref, a, v, tau, work[2 * n :])


def ctc_linear_gains(g: FloatArray, smc_model: FloatArray, mass: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Around the reference the torque's error feedback is ``Mhat (Kp e + Kd edot)``: in torque
    terms ``Kp_eff = s_M Mbar diag(omega_n^2)``, ``Kd_eff = s_M Mbar diag(2 zeta omega_n)``, so the
    check's ``Mbar^{-1} Kp_eff`` is ``s_M omega_n^2`` (the exact model: ``edd + Kd ed + Kp e = 0``)."""
    w, z = g[OMEGA], g[ZETA]
    s_m = float(smc_model[S_MASS])
    return s_m * mass @ np.diag(w * w), s_m * mass @ np.diag(2.0 * z * w)


def ctc_presets(source: Mapping[str, FloatArray], model: Manipulator, q0: FloatArray) -> dict[str, FloatArray]:
    """omega_n and zeta from the PD's presets: ``omega_n_i = sqrt(Kp_i / Mbar_ii(q0))``, ``zeta_i = 1``.

    ``omega_n`` gives each joint the PD preset's stiffness at the reference's start ``q0``
    (where ``Kp_i / Mbar_ii`` is the PD's squared natural frequency of that joint alone), so the
    two laws respond to an error at the same speed; ``zeta = 1``, critically damped, the
    fastest response without overshoot (the PD presets' own damping ratios at the start,
    ``Kd_i / (2 sqrt(Kp_i Mbar_ii))``, range from 0.35 on the UR5 to 3-4 on the five-bar and
    15-45 on the serial arm, circle: not a choice a computed-torque design would copy).
    """
    diag = np.diagonal(model.mass_matrix(q0))
    omega = np.sqrt(np.asarray(source["kp"], dtype=float) / diag)
    return {"omega_n": omega, "zeta": np.ones_like(omega)}


PDG_LAW = LawEntry("pdg", "PD+G", (GAIN_KP, GAIN_KD), equation="PD + gravity compensation (Takegaki & Arimoto 1981)",
                   code=PDG, linear_gains=pd_linear_gains, rows=THESIS_ROWS, model_based=True, presets_from="pd")
CTC_LAW = LawEntry("ctc", "CTC", CTC_ROWS, equation="computed torque (Spong et al. 2006, Sec. 8.3)", code=CTC,
                   linear_gains=ctc_linear_gains, model_based=True, presets_from="pd", derive_presets=ctc_presets)
