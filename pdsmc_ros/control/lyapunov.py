"""The sufficient stability conditions of the PD-SMC theorem (Eq. 3.19) along a motion.

For the hybrid law of Eq. (3.17), Section 3.5 proves global asymptotic
stability when, at every instant,

    lambda > 0
    Ks > ||tau_d||                                   (tau_d of Eq. 3.3)
    K + C^T > 0
    lambda_m(Kd) > lambda * lambda_M(M)
    lambda_m(Kp) > lambda^2 * lambda_M(M)
    lambda_m(Kd) > 1/2 * lambda_M(K + C^T)
    lambda_m(Kd - lambda M) > lambda/2 * lambda_M(K + C^T)

with ``K`` any constant positive definite matrix. The thesis writes lambda as
a scalar; with per-joint slopes the largest one is used (the conservative
reading). ``K = kappa I`` is chosen as the smallest multiple of the identity
that makes ``K + C^T`` positive definite along the whole motion (plus 1 %),
which leaves the most room for the last two conditions. ``Ks > ||tau_d||`` is
checked per joint (``Ks_i > max_t |tau_d,i|``) as the switching term acts per
joint. Quantities of a non-symmetric matrix use its symmetric part.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .law_run import LawRun


@dataclass(frozen=True)
class Condition:
    """One inequality ``lhs > rhs`` evaluated at its worst instant."""

    name: str
    lhs: float
    rhs: float

    @property
    def holds(self) -> bool:
        return self.lhs > self.rhs

    @property
    def margin(self) -> float:
        """``lhs / rhs`` (> 1 holds); ``inf`` when ``rhs <= 0`` and it holds."""
        if self.rhs <= 0.0:
            return float("inf") if self.holds else 0.0
        return self.lhs / self.rhs


def _sym(a: np.ndarray) -> np.ndarray:
    return np.asarray(0.5 * (a + np.swapaxes(a, -1, -2)))


def theorem_conditions(spec: LawRun, *, points: int = 401) -> list[Condition]:
    """Eq. (3.19) evaluated on ``points`` instants of the desired motion."""
    robot = spec.nominal_model()
    reference = spec.reference()
    t = np.linspace(0.0, reference.duration, points)
    ref = reference.sample(t)
    q, qd, qdd = ref.q, ref.qd, ref.qdd
    mass = robot.mass_matrix(q)
    cor = robot.coriolis_matrix(q, qd)
    # tau_d of Eq. (3.3) with this plant's damping: M qdd_d + C qd_d + B qd_d + G
    tau_d = (
        np.einsum("kij,kj->ki", mass, qdd)
        + np.einsum("kij,kj->ki", cor, qd)
        + robot.B * qd
        + robot.gravity(q)
    )
    g = spec.gains
    kp, kd, ks, lam = (np.asarray(x, dtype=float) for x in (g["kp"], g["kd"], g["ks"], g["lam"]))
    lam_max = float(lam.max())
    m_max = float(np.max(np.linalg.eigvalsh(mass)))
    ct_sym = _sym(np.swapaxes(cor, -1, -2))
    kappa = max(float(np.max(-np.linalg.eigvalsh(ct_sym))), 0.0) * 1.01 + 1e-9
    k_ct = kappa * np.eye(robot.n) + ct_sym
    k_ct_max = float(np.max(np.linalg.eigvalsh(k_ct)))
    k_ct_min = float(np.min(np.linalg.eigvalsh(k_ct)))
    kd_minus = np.diag(kd) - lam_max * mass
    conditions = [Condition("lambda > 0", float(lam.min()), 0.0)]
    worst = np.max(np.abs(tau_d), axis=0)
    for i in range(robot.n):
        conditions.append(Condition(f"Ks_{i + 1} > max |tau_d,{i + 1}|", float(ks[i]), float(worst[i])))
    conditions += [
        Condition(f"K + C^T > 0 (K = {kappa:.4g} I)", k_ct_min, 0.0),
        Condition("lambda_m(Kd) > lambda lambda_M(M)", float(kd.min()), lam_max * m_max),
        Condition("lambda_m(Kp) > lambda^2 lambda_M(M)", float(kp.min()), lam_max**2 * m_max),
        Condition("lambda_m(Kd) > lambda_M(K + C^T) / 2", float(kd.min()), 0.5 * k_ct_max),
        Condition(
            "lambda_m(Kd - lambda M) > lambda/2 lambda_M(K + C^T)",
            float(np.min(np.linalg.eigvalsh(kd_minus))),
            0.5 * lam_max * k_ct_max,
        ),
    ]
    return conditions
