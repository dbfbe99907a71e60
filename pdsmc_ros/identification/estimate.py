"""The base parameters by weighted least squares, with their standard errors.

Gautier's two steps (Gautier & Poignet 2001; Swevers et al. 1997): ordinary least squares on
the base regressor gives each joint's residual standard deviation ``sigma_j``; each torque
equation is then weighed by ``1 / sigma_j`` (the joints' efforts differ by orders of
magnitude, the wrists' by less than a newton metre) and solved again. With the whitened base
regressor ``A = Q R``, ``beta = R^-1 Q^T b`` and the covariance ``R^-1 R^-T`` (``sigma_j``
already in the weights), whose diagonal's roots are the standard errors. Solved by QR, never
by the normal equations.

Before that, the motion must determine every base parameter: :func:`check_excitation` says
which ones it does not and why (a joint that did not move, too few samples), and the
identification stops there rather than give numbers the data did not decide.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg

from ..errors import InvalidInputError
from ..robots.base import FloatArray
from .base import BaseParameters
from .model import ArmDynamics

__all__ = ["BaseEstimate", "NotIdentifiableError", "Rows", "build_rows", "check_excitation", "nrmse",
           "weighted_least_squares"]

SIGMA_FLOOR = 1e-9
"""The smallest residual standard deviation a joint is weighed by, as a share of its effort's
RMS: data without noise would otherwise weigh infinitely."""
RANK_TOLERANCE = 1e-9
"""A singular value of the column-scaled base regressor below this share of the largest: a
direction the motion does not determine."""
SAMPLES_PER_PARAMETER = 10
"""A run must give at least this many torque equations per base parameter: fewer, and one period
of noise or of a model error decides the estimate (at the kept rate, 2.5 cut-offs, ten a parameter
is about 12 s of a UR5 excitation of the default 0.5 Hz bandwidth)."""
MOVED = 1e-3
"""A joint that moved less than this (rad or m, peak to peak) did not move."""


class NotIdentifiableError(InvalidInputError):
    """The run does not determine some base parameters (its message says which and why)."""


@dataclass(frozen=True)
class Rows:
    """The torque equations the fit uses: the standard regressor's rows, their efforts and joints."""

    regressor: FloatArray
    tau: FloatArray
    joint: np.ndarray

    @property
    def size(self) -> int:
        return len(self.tau)

    @classmethod
    def of(cls, regressor: FloatArray, tau: FloatArray, moving: np.ndarray | None = None) -> Rows:
        """The equations of a regressor ``(k * n, p)`` and efforts ``(k, n)``, leaving out joint
        ``j``'s at samples where ``moving[s, j]`` is false."""
        k, n = np.shape(tau)
        keep = np.ones(k * n, dtype=bool) if moving is None else np.asarray(moving, dtype=bool).reshape(-1)
        joint = np.tile(np.arange(n), k)
        return cls(regressor[keep], np.asarray(tau, dtype=float).reshape(-1)[keep], joint[keep])


def build_rows(dynamics: ArmDynamics, q: FloatArray, qd: FloatArray, qdd: FloatArray, tau: FloatArray,
               moving: np.ndarray | None = None) -> Rows:
    """The equations of samples ``(k, n)``, leaving out joint ``j``'s at samples where
    ``moving[s, j]`` is false (its velocity reversal: :mod:`.signals`)."""
    return Rows.of(dynamics.regressor(q, qd, qdd), tau, moving)


@dataclass(frozen=True)
class BaseEstimate:
    """The weighted least-squares base parameters.

    Attributes
    ----------
    values, standard_errors : ndarray, shape (r,)
    covariance : ndarray, shape (r, r)
    sigma : ndarray, shape (n,)
        Each joint's residual standard deviation (N m), the weights' ``1 / sigma``.
    root : ndarray, shape (r, r)
        ``R`` of the whitened base regressor: ``||R (beta' - beta)||^2`` is how much a change of
        the base parameters adds to the weighted residual (in units of the weights).
    """

    values: FloatArray
    standard_errors: FloatArray
    covariance: FloatArray
    sigma: FloatArray
    root: FloatArray


def _solve(a: FloatArray, b: FloatArray) -> tuple[FloatArray, FloatArray]:
    q_factor, r_factor = scipy.linalg.qr(a, mode="economic")
    return scipy.linalg.solve_triangular(r_factor, q_factor.T @ b), r_factor


def weighted_least_squares(base: BaseParameters, rows: Rows, n: int) -> BaseEstimate:
    """Gautier's two steps (module docstring)."""
    yb = base.columns(rows.regressor)
    first, _ = _solve(yb, rows.tau)
    residual = rows.tau - yb @ first
    dof = max(rows.size - base.size, 1)
    sigma = np.zeros(n)
    for j in range(n):
        mine = rows.joint == j
        count = int(mine.sum())
        share = count / rows.size if rows.size else 0.0
        rms = float(np.sqrt(np.mean(rows.tau[mine] ** 2))) if count else 0.0
        # each joint's share of the degrees of freedom (the estimate used some of every joint's)
        spread = float(np.sum(residual[mine] ** 2) / max(dof * share, 1.0)) if count else 0.0
        sigma[j] = max(np.sqrt(spread), SIGMA_FLOOR * max(rms, 1e-12))
    weights = 1.0 / sigma[rows.joint]
    values, root = _solve(yb * weights[:, None], rows.tau * weights)
    inverse_root = scipy.linalg.solve_triangular(root, np.eye(base.size))
    covariance = inverse_root @ inverse_root.T
    return BaseEstimate(values, np.sqrt(np.diag(covariance)), covariance, sigma, root)


def nrmse(measured: FloatArray, predicted: FloatArray) -> FloatArray:
    """Per joint: the RMS of ``measured - predicted`` over the range of ``measured`` (max - min)."""
    measured = np.asarray(measured, dtype=float)
    spread = measured.max(axis=0) - measured.min(axis=0)
    rms = np.sqrt(np.mean((measured - predicted) ** 2, axis=0))
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(spread > 0.0, rms / spread, np.inf)


def check_excitation(dynamics: ArmDynamics, base: BaseParameters, rows: Rows, q: FloatArray) -> None:
    """Refuse a run that does not determine every base parameter.

    Raises
    ------
    NotIdentifiableError
        One line: too few equations for the base parameters; or the base parameters the
        run's regressor leaves undetermined (its numerical null space, columns scaled to unit
        norm), with the joints that did not move (the likely reason) or, if all moved, that
        the motion does not separate them.
    """
    names = dynamics.layout.joint_names
    needed = SAMPLES_PER_PARAMETER * base.size
    if rows.size < needed:
        raise NotIdentifiableError(
            f"run too short: {rows.size} torque equations after filtering for {base.size} base parameters (at least "
            f"{needed}); record longer (several periods of the excitation)")
    spread = q.max(axis=0) - q.min(axis=0)
    still = [names[j] for j in range(len(names)) if spread[j] < MOVED]
    yb = base.columns(rows.regressor)
    norms = np.linalg.norm(yb, axis=0)
    scaled = yb / np.where(norms > 0.0, norms, 1.0)
    _, singular, vt = np.linalg.svd(scaled, full_matrices=False)
    weak = singular <= RANK_TOLERANCE * singular[0]
    null = vt[weak] if np.any(weak) else np.zeros((0, base.size))
    zero_columns = np.flatnonzero(norms <= RANK_TOLERANCE * norms.max())
    involved = set(zero_columns.tolist())
    if len(null):
        involved |= set(np.flatnonzero(np.max(np.abs(null), axis=0) > 1e-3).tolist())
    if not involved:
        return
    listed = sorted(involved)
    shown = "; ".join(base.names[k] for k in listed[:4]) + (f"; and {len(listed) - 4} more" if len(listed) > 4 else "")
    if still:
        why = f"joint(s) {', '.join(still)} did not move (peak to peak below {MOVED:g})"
    else:
        friction = [names[j] for j in range(len(names)) if not np.any(rows.joint == j)]
        why = (f"joint(s) {', '.join(friction)} never moved outside the dead zone around their velocity reversals"
               if friction else "the motion does not separate them: excite every joint (pdsmc excite)")
    raise NotIdentifiableError(f"not exciting enough: the run determines {base.size - len(listed)} of {base.size} base "
                               f"parameters; not identifiable: {shown} -- {why}")
