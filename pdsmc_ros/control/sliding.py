"""Sliding-mode laws beside the thesis's SMC: super-twisting and integral sliding mode.

Both are the SMC's model-based part (Eq. 3.15 without its switching term,
:func:`~pdsmc_ros.control.laws.model_part`) plus a term of their own, and both integrate a
state (:attr:`LawEntry.state_size` = 1 per joint, stepped once per control period ``h``,
explicit Euler: the torque of instant ``k`` uses the state of instant ``k``). Written once,
compiled. Errors ``e = q_d - q``, ``edot = qd_d - qd``
(Eq. 3.2), so with ``M sdot = -(C + B) s - (the law's own term)`` for the exact model, the own
term enters with a plus sign.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np
from numba import njit

from ..kernels.options import ALLOCATION_FREE
from ..robots.base import FloatArray, Manipulator
from .laws import GAIN_KS, GAIN_LAM, GAIN_PHI, model_part
from .registry import S_MASS, GainSpec, LawEntry

STA = 5
ISMC = 6
"""Codes of the compiled forms."""

GAIN_K1 = GainSpec("k1", "super-twisting gains k1 of k1 |s|^(1/2) sign(s) (Levant 1993)", "N m/(rad/s)^(1/2)",
                   lower_open=True, neutral=1.0, scaled_by="ks")
GAIN_K2 = GainSpec("k2", "super-twisting gains k2 of vdot = k2 sign(s) (Levant 1993)", "N m/s",
                   lower_open=True, neutral=1.0, scaled_by="ks")
STA_ROWS = (GAIN_K1, GAIN_K2, GAIN_LAM)
K1, K2, STA_LAM = range(3)
ISMC_ROWS = (GAIN_KS, GAIN_LAM, GAIN_PHI)
I_KS, I_LAM, I_PHI = range(3)

LEVANT_K1 = 1.5
LEVANT_K2 = 1.1
"""Levant's (1993) gains for a perturbation of Lipschitz constant L: ``k1 = 1.5 sqrt(L)``, ``k2 = 1.1 L``."""


@njit(cache=True, inline="always")
def _scratch(work, n):  # noqa: ANN001, ANN202
    """Four length-``n`` blocks at the start of ``work`` (``qdd_r``, ``qd_r`` and two of the law's
    own) and the rest of it, for :func:`model_part` (inlined: the very slices the law would take)."""
    return work[0:n], work[n : 2 * n], work[2 * n : 3 * n], work[3 * n : 4 * n], work[4 * n :]


@njit(**ALLOCATION_FREE)
def sta(g, m, kind, p, q, qd, q_ref, qd_ref, qdd_ref, tau, work, state, h):  # noqa: ANN001, ANN201, PLR0913
    """Super-twisting SMC: the SMC's model part plus ``k1 |s|^(1/2) sign(s) + v``, ``vdot = k2 sign(s)``.

    ``s = lambda e + edot`` (Eq. 3.13), ``qdd_r = qdd_d + lambda edot``, ``qd_r = qd_d + lambda e``;
    ``v = state[0]``. Levant 1993, "Sliding-order and sliding accuracy in sliding mode control",
    Int. J. Control 58(6), Eq. (super-twisting algorithm); gains after Moreno & Osorio 2012,
    "Strict Lyapunov functions for the super-twisting algorithm", IEEE TAC 57(4). Continuous
    torque: the discontinuity is in ``vdot`` only.
    """
    n = q.shape[0]
    qdd_r, qd_r, sign, root, rest = _scratch(work, n)
    for i in range(n):
        e = q_ref[i] - q[i]
        ed = qd_ref[i] - qd[i]
        s = g[STA_LAM, i] * e + ed
        qdd_r[i] = qdd_ref[i] + g[STA_LAM, i] * ed
        qd_r[i] = qd_ref[i] + g[STA_LAM, i] * e
        sign[i] = 1.0 if s > 0.0 else (-1.0 if s < 0.0 else 0.0)
        root[i] = g[K1, i] * math.sqrt(abs(s)) * sign[i]
    model_part(m, kind, p, q, qd, q_ref, qd_ref, qdd_r, qd_r, tau, rest)
    for i in range(n):
        tau[i] += root[i] + state[0, i]
        state[0, i] += h * g[K2, i] * sign[i]


@njit(**ALLOCATION_FREE)
def ismc(g, m, kind, p, q, qd, q_ref, qd_ref, qdd_ref, tau, work, state, h):  # noqa: ANN001, ANN201, PLR0913
    """Integral SMC: the SMC's model part on ``s = edot + 2 lambda e + lambda^2 z``, ``z = int e dt``.

    ``qd_r = qd_d + 2 lambda e + lambda^2 z``, ``qdd_r = qdd_d + 2 lambda edot + lambda^2 e``
    (so ``s = qd_r - qd``), plus ``Ks sat(s / phi)`` (Eq. 3.45); ``z = state[0]``. Integral
    sliding mode after Utkin & Shi 1996, "Integral sliding mode in systems operating under
    uncertainty conditions", Proc. 35th IEEE CDC; the surface is Slotine & Li's integral one
    (1991, "Applied Nonlinear Control", Section 7.1: ``s = (d/dt + lambda)^2 int e``), which
    removes the steady error a constant model mismatch (the gravity estimate's) leaves
    inside the boundary layer.
    """
    n = q.shape[0]
    qdd_r, qd_r, sat, err, rest = _scratch(work, n)
    for i in range(n):
        lam = g[I_LAM, i]
        e = q_ref[i] - q[i]
        ed = qd_ref[i] - qd[i]
        qd_r[i] = qd_ref[i] + 2.0 * lam * e + lam * lam * state[0, i]
        qdd_r[i] = qdd_ref[i] + 2.0 * lam * ed + lam * lam * e
        s = (qd_r[i] - qd[i]) / g[I_PHI, i]
        sat[i] = 1.0 if s > 1.0 else (-1.0 if s < -1.0 else s)
        err[i] = e
    model_part(m, kind, p, q, qd, q_ref, qd_ref, qdd_r, qd_r, tau, rest)
    for i in range(n):
        tau[i] += g[I_KS, i] * sat[i]
        state[0, i] += h * err[i]


def sta_presets(source: Mapping[str, FloatArray], model: Manipulator,  # noqa: ARG001
                q0: FloatArray) -> dict[str, FloatArray]:  # noqa: ARG001
    """k1, k2 from the SMC's presets: ``k1 = Ks / sqrt(phi)``, ``k2 = 1.1 L`` with ``k1 = 1.5 sqrt(L)``.

    ``k1 |s|^(1/2)`` equals the SMC's switching torque ``Ks sat(s / phi)`` at ``|s| = phi``
    (the edge of its boundary layer) and exceeds it inside; ``k2`` completes Levant's classical
    pair ``k1 = 1.5 sqrt(L)``, ``k2 = 1.1 L`` (Levant 1998, "Robust exact differentiation via
    sliding mode technique", Automatica 34(3)) for that ``k1``: ``L = (k1 / 1.5)^2`` is the
    bound on the perturbation's rate those gains cover. Moreno and Osorio (2012) prove the
    algorithm's finite-time convergence for any ``k1, k2 > 0`` unperturbed, with conditions on
    both under a perturbation; here the relation is applied in torque units (the bound in
    ``sdot`` is ``L`` over the joint's inertia): a documented starting point, not a proof for the arm.
    """
    k1 = np.asarray(source["ks"], dtype=float) / np.sqrt(np.asarray(source["phi"], dtype=float))
    return {"k1": k1, "k2": LEVANT_K2 * (k1 / LEVANT_K1) ** 2}


def ismc_presets(source: Mapping[str, FloatArray], model: Manipulator, q0: FloatArray) -> dict[str, FloatArray]:
    """lambda from the SMC's presets, so that the ISMC's linear part is the SMC's plus its integral.

    Inside the boundary layer the SMC (Eq. 3.15, ``s = edot + lambda e``) feeds the error back
    with ``Kp = lambda_S Ks / phi``, ``Kd = s_M Mbar lambda_S + Ks / phi``; the ISMC on the
    integral surface ``s = edot + 2 lambda e + lambda^2 int e`` (Slotine & Li 1991, Section 7.1)
    with ``Kp = Mbar lambda^2 + 2 lambda Ks / phi``, ``Kd = 2 Mbar lambda + Ks / phi`` (exact
    model, :func:`ismc_linear_gains`) and ``lambda^2 Ks / phi`` on ``int e``. Integral sliding
    mode adds its integral to a nominal design and keeps that design's closed loop (Utkin & Shi
    1996, "Integral sliding mode in systems operating under uncertainty conditions", Proc. 35th
    IEEE CDC), so each joint's ``lambda`` solves ``Mbar_ii lambda^2 + 2 lambda Ks / phi =
    lambda_S Ks / phi`` at the reference's start ``q0``: the SMC's stiffness, which the SMC's
    presets were tuned (and checked for the real-time loop) with,

        ``lambda = lambda_S / (1 + sqrt(1 + Mbar_ii(q0) lambda_S phi / Ks))``,

    below ``lambda_S / 2``, so the damping ``2 Mbar_ii lambda + Ks / phi`` is at most the SMC's
    (the two are equal for a massless joint, ``2 lambda = lambda_S``). With the model's estimate
    ``s_M Mbar``, ``s_M <= 1``, both are at most the SMC's. The SMC's ``lambda`` as it is would
    double the damping term; the real-time stability check refuses it on the UR5 and the Panda at
    1 kHz. ``Ks`` and ``phi`` are the SMC's (copied by :meth:`LawEntry.presets_of`).
    """
    lam = np.asarray(source["lam"], dtype=float)
    ks_phi = np.asarray(source["ks"], dtype=float) / np.asarray(source["phi"], dtype=float)
    inertia = np.diagonal(model.mass_matrix(q0))
    return {"lam": lam / (1.0 + np.sqrt(1.0 + inertia * lam / ks_phi))}


def ismc_linear_gains(g: FloatArray, smc_model: FloatArray, mass: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Inside the boundary layer, as the SMC's with the surface's ``2 lambda`` and ``lambda^2``:
    ``Kp_eff = s_M Mbar lambda^2 + 2 lambda Ks / phi``, ``Kd_eff = s_M Mbar 2 lambda + Ks / phi``.
    The integral state is left out (the check's error map has no integrator): its gain
    ``lambda^2 Ks / phi`` acts at ``lambda``, far below the rates the check bounds."""
    ks_phi = np.diag(g[I_KS] / g[I_PHI])
    lam = np.diag(g[I_LAM])
    s_m = float(smc_model[S_MASS])
    return s_m * mass @ lam @ lam + 2.0 * ks_phi @ lam, 2.0 * s_m * mass @ lam + ks_phi


STA_LAW = LawEntry("sta", "STA", STA_ROWS, equation="super-twisting (Levant 1993)", code=STA,
                   model_based=True, state_size=1, presets_from="smc", derive_presets=sta_presets)
ISMC_LAW = LawEntry("ismc", "ISMC", ISMC_ROWS, equation="integral sliding mode (Utkin & Shi 1996)", code=ISMC,
                    linear_gains=ismc_linear_gains, model_based=True,
                    state_size=1, presets_from="smc", derive_presets=ismc_presets)
