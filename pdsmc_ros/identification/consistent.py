"""Physically consistent standard parameters: a semidefinite program (an LMI per body).

The least-squares base parameters (:mod:`.estimate`) are what the data determine; a model the
laws and a simulator can use needs standard parameters -- each link a body of positive mass
whose inertia about its centre of mass is positive definite and obeys the triangle
inequalities, no negative friction or motor inertia. A body's ten parameters are those of a
body of positive density exactly when its pseudo-inertia is positive semidefinite (Wensing,
Kim & Slotine, "Linear matrix inequalities for physically consistent inertial parameter
identification", IEEE RA-L 2017); positive *definite* (the margin :data:`MARGIN`) gives the
strict conditions. Those are linear matrix inequalities, and the fit a convex semidefinite
program, solved here by Clarabel (an interior-point conic solver):

1. ``minimize ||pi - pi_0||_W`` subject to ``K pi = beta`` (the least-squares base
   parameters, exactly) and the LMIs: the data decide every base parameter, the arm's own
   parameters ``pi_0`` (its URDF and options: :attr:`ArmDynamics.nominal`) decide the rest --
   the combinations the torques cannot see. ``W`` weighs each link's parameters by the link's
   scale (its mass, and lengths of the arm) and the payload's, the motor inertias' and the
   frictions' a billion times less: where the data allow, a difference from the URDF is put
   on them rather than on the links (the URDF's links are its best knowledge; the payload, the
   motors and the friction are what it does not know).
2. If no consistent parameters give those base parameters exactly (noise made the estimate
   impossible, say a negative friction), the nearest consistent ones in the estimate's own
   metric -- ``minimize ||R (K pi - beta)||^2`` (the increase of the weighted residual) plus
   a small share of step 1's objective, under the LMIs -- and step 1 again with those.

Standard errors: without active constraints, step 1's answer is linear in ``beta``,
``pi = pi_0 + G (beta - K pi_0)`` with ``G = W^-1 K^T (K W^-1 K^T)^-1``, so its covariance is
``G Sigma_beta G^T``: the data's uncertainty carried to each standard parameter, given the
URDF in the directions the data do not see (:attr:`ConsistentFit.standard_errors`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.sparse
from numpy.typing import ArrayLike

from ..errors import PdsmcError
from ..robots.base import FloatArray
from .base import BaseParameters
from .estimate import BaseEstimate
from .model import JOINT_FIELDS, ArmDynamics, pseudo_inertia

__all__ = ["MARGIN", "ConsistentFit", "consistent_fit", "is_consistent", "parameter_scales"]

MARGIN = 1e-6
"""Each link's pseudo-inertia exceeds this share of its scale (a link of mass ``m_s`` and
size ``L``: ``diag(m_s L^2, m_s L^2, m_s L^2, m_s)``): strictly a body."""
FREE_WEIGHT = 1e-9
"""The weight of the payload's, motor inertias' and frictions' distance from the arm's own values,
against the links' (each in its own scale)."""
PROJECTION_PRIOR = 1e-6
"""Step 2's share of step 1's objective (which picks among the nearest consistent estimates)."""


class FitError(PdsmcError):
    """The solver failed (its status in the message)."""


@dataclass(frozen=True)
class ConsistentFit:
    """Physically consistent standard parameters.

    Attributes
    ----------
    values : ndarray, shape (p,)
        The standard parameters (:class:`~.model.ParameterLayout`).
    standard_errors : ndarray, shape (p,)
        ``sqrt(diag(G Sigma_beta G^T))`` (module docstring).
    projected : bool
        The least-squares estimate was not consistent: the base parameters were moved (step 2).
    shift : float
        How far the base parameters moved: ``||R (K pi - beta)||``, in the weighted residual's
        units (0 when not projected).
    """

    values: FloatArray
    standard_errors: FloatArray
    projected: bool
    shift: float


def parameter_scales(dynamics: ArmDynamics) -> FloatArray:
    """A scale per standard parameter: a link's mass ``m_s`` (its URDF mass, at least 5 % of the
    arm's moving mass), its first moments ``m_s L`` and inertias ``m_s L^2`` (``L`` the mean
    distance between the arm's successive joints, at least 5 cm); the payload's as the
    end-effector link's; motor inertias as the largest link's ``m_s L^2``; frictions as 5 % of
    each joint's effort limit (or 1 N m)."""
    layout = dynamics.layout
    nominal = dynamics.nominal
    n = dynamics.n
    masses = np.array([nominal[layout.link(i)][0] for i in range(n)])
    floor = 0.05 * max(float(masses.sum()), 1e-3)
    mass_scale = np.maximum(masses, floor)
    length = _joint_spacing(dynamics)
    out = np.empty(layout.size)
    per_body = np.array([1.0, length, length, length, *([length**2] * 6)])
    for i in range(n):
        out[layout.link(i)] = mass_scale[i] * per_body
    out[layout.payload] = mass_scale[dynamics.payload_joint] * per_body
    out[layout.joint_field("armature")] = float(mass_scale.max()) * length**2
    effort = np.where(np.isfinite(dynamics.arm.effort_limits), 0.05 * dynamics.arm.effort_limits, 1.0)
    out[layout.joint_field("friction_coulomb")] = effort
    out[layout.joint_field("friction_viscous")] = effort
    return out


def _joint_spacing(dynamics: ArmDynamics) -> float:
    model = dynamics.model
    gaps = [float(np.linalg.norm(model.jointPlacements[i].translation)) for i in range(2, model.njoints)]
    gaps = [g for g in gaps if g > 1e-6]
    return max(float(np.mean(gaps)) if gaps else 0.0, 0.05)


def _svec_rows(size: int = 4) -> list[tuple[int, int, float]]:
    """Clarabel's PSD-triangle order: the upper triangle column by column, off-diagonals times sqrt 2."""
    out = []
    for col in range(size):
        for row in range(col + 1):
            out.append((row, col, 1.0 if row == col else np.sqrt(2.0)))
    return out


def _pseudo_inertia_matrix() -> FloatArray:
    """The 10 x 10 linear map from ten parameters to the svec of their pseudo-inertia."""
    out = np.empty((10, 10))
    for k in range(10):
        e = np.zeros(10)
        e[k] = 1.0
        j = pseudo_inertia(e)
        out[:, k] = [scale * j[r, c] for r, c, scale in _svec_rows()]
    return out


def _svec(matrix: FloatArray) -> FloatArray:
    return np.array([scale * matrix[r, c] for r, c, scale in _svec_rows()])


def is_consistent(parameters: ArrayLike, dynamics: ArmDynamics, *, margin: float = 0.0) -> np.ndarray:
    """Per link, whether its parameters are a body's (pseudo-inertia positive definite beyond
    ``margin`` of its scale), then the payload's (semidefinite), then each joint parameter >= 0."""
    p = np.asarray(parameters, dtype=float)
    layout = dynamics.layout
    scales = parameter_scales(dynamics)
    out = []
    for i in range(dynamics.n):
        s = scales[layout.link(i)]
        floor = margin * np.diag([s[4], s[4], s[4], s[0]])
        out.append(bool(np.linalg.eigvalsh(pseudo_inertia(p[layout.link(i)]) - floor)[0] > 0.0))
    out.append(bool(np.linalg.eigvalsh(pseudo_inertia(p[layout.payload]))[0] >= -1e-12))
    for field in JOINT_FIELDS:
        out.extend(bool(v >= 0.0) for v in p[layout.joint_field(field)])
    return np.array(out)


def _constraints(dynamics: ArmDynamics, scales: FloatArray) -> tuple[list[FloatArray], list[FloatArray], list[Any]]:
    """The LMIs and bounds as Clarabel's ``A x + s = b, s in K``: rows, right-hand sides, cones."""
    import clarabel

    layout = dynamics.layout
    p = layout.size
    to_svec = _pseudo_inertia_matrix()
    rows: list[FloatArray] = []
    rhs: list[FloatArray] = []
    cones: list[Any] = []
    for i in range(dynamics.n):
        a = np.zeros((10, p))
        a[:, layout.link(i)] = -to_svec
        s = scales[layout.link(i)]
        rows.append(a)
        rhs.append(-_svec(MARGIN * np.diag([s[4], s[4], s[4], s[0]])))
        cones.append(clarabel.PSDTriangleConeT(4))
    a = np.zeros((10, p))
    a[:, layout.payload] = -to_svec
    rows.append(a)
    rhs.append(np.zeros(10))
    cones.append(clarabel.PSDTriangleConeT(4))
    bounded = np.concatenate([np.arange(p)[layout.joint_field(f)] for f in JOINT_FIELDS])
    a = np.zeros((len(bounded), p))
    a[np.arange(len(bounded)), bounded] = -1.0
    rows.append(a)
    rhs.append(np.zeros(len(bounded)))
    cones.append(clarabel.NonnegativeConeT(len(bounded)))
    return rows, rhs, cones


def _solve(hessian: FloatArray, linear: FloatArray, rows: list[FloatArray], rhs: list[FloatArray], cones: list[Any]
           ) -> tuple[FloatArray | None, str]:
    import clarabel

    settings = clarabel.DefaultSettings()
    settings.verbose = False
    settings.tol_gap_abs = settings.tol_gap_rel = 1e-10
    settings.tol_feas = 1e-10
    settings.max_iter = 400
    p_matrix = scipy.sparse.csc_matrix(np.triu(hessian))
    a_matrix = scipy.sparse.csc_matrix(np.vstack(rows))
    solver = clarabel.DefaultSolver(p_matrix, linear, a_matrix, np.concatenate(rhs), cones, settings)
    solution = solver.solve()
    status = str(solution.status)
    if status.endswith("Solved") and "Almost" not in status:
        return np.asarray(solution.x, dtype=float), status
    if status.endswith("AlmostSolved"):
        return np.asarray(solution.x, dtype=float), status
    return None, status


def consistent_fit(dynamics: ArmDynamics, base: BaseParameters, estimate: BaseEstimate) -> ConsistentFit:
    """Steps 1 and 2 of the module docstring.

    Raises
    ------
    FitError
        The solver found no answer (its status named).
    """
    scales = parameter_scales(dynamics)
    layout = dynamics.layout
    weights = 1.0 / scales**2
    free = np.ones(layout.size, dtype=bool)
    free[layout.links] = False
    weights[free] *= FREE_WEIGHT
    prior = dynamics.nominal
    k = base.grouping
    # work in units of the scales (x = pi / scale): every variable of order one for the solver
    k_scaled = k * scales[None, :]
    w_scaled = weights * scales**2
    rows, rhs, cones = _constraints(dynamics, scales)
    rows = [r * scales[None, :] for r in rows]

    def nearest(beta: FloatArray) -> FloatArray | None:
        hessian = np.diag(w_scaled)
        linear = -w_scaled * (prior / scales)
        x, _ = _solve(hessian, linear, [k_scaled, *rows], [beta, *rhs], [_zero(len(beta)), *cones])
        return None if x is None else x * scales

    values = nearest(estimate.values)
    projected, shift = False, 0.0
    if values is None:
        # step 2: the nearest consistent base parameters in the estimate's metric
        data = estimate.root @ k_scaled
        hessian = data.T @ data
        linear = -data.T @ (estimate.root @ estimate.values)
        top = float(np.max(np.diag(hessian))) or 1.0
        hessian = hessian / top + PROJECTION_PRIOR * np.diag(w_scaled)
        linear = linear / top - PROJECTION_PRIOR * w_scaled * (prior / scales)
        x, status = _solve(hessian, linear, rows, rhs, cones)
        if x is None:
            raise FitError(f"the physically consistent fit failed: the solver ended {status}")
        projected_values = x * scales
        beta = k @ projected_values
        again = nearest(beta)
        values = projected_values if again is None else again
        projected = True
        shift = float(np.linalg.norm(estimate.root @ (k @ values - estimate.values)))
    values = _polished(values, dynamics)
    inverse = 1.0 / weights
    middle = k @ (inverse[:, None] * k.T)
    gain = (inverse[:, None] * k.T) @ np.linalg.solve(middle, np.eye(len(middle)))
    covariance = gain @ estimate.covariance @ gain.T
    return ConsistentFit(values, np.sqrt(np.maximum(np.diag(covariance), 0.0)), projected, shift)


def _polished(values: FloatArray, dynamics: ArmDynamics) -> FloatArray:
    """The solver's answer on its constraints' boundary to working precision: a motor inertia or a
    friction of -1e-12 is 0, the payload's pseudo-inertia's eigenvalues of -1e-11 are 0 (the
    interior-point solver stops within its tolerance of a boundary it approaches)."""
    out = values.copy()
    layout = dynamics.layout
    for field in JOINT_FIELDS:
        part = layout.joint_field(field)
        out[part] = np.maximum(out[part], 0.0)
    eigenvalues, vectors = np.linalg.eigh(pseudo_inertia(out[layout.payload]))
    if eigenvalues[0] < 0.0:
        j = vectors @ np.diag(np.maximum(eigenvalues, 0.0)) @ vectors.T
        sigma = j[:3, :3]
        inertia = np.trace(sigma) * np.eye(3) - sigma
        out[layout.payload] = [j[3, 3], *j[:3, 3], inertia[0, 0], inertia[0, 1], inertia[1, 1], inertia[0, 2],
                               inertia[1, 2], inertia[2, 2]]
    return out


def _zero(size: int) -> Any:
    import clarabel

    return clarabel.ZeroConeT(size)
