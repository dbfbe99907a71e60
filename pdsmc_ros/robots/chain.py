"""Planar serial chains: the numpy reference and the compiled terms side by side.

The building block of both thesis robots. Written in absolute link angles
``theta = L q`` (``L`` lower-triangular ones), the inertia matrix is
``W o cos(theta_a - theta_b) + diag(I)`` with the constant
``W_ab = sum_k m_k l_ka l_kb`` (``l_ka`` the lever of link ``k``'s mass centre
along link ``a``), which makes mass matrix, Coriolis and gravity terms a few
vectorised lines, exact for any number of links and any payload.

The thesis arms write the mass matrix and ``C qd + G`` out in scalars for their
fixed link counts (``serial_3r._terms``, ``parallel_5r_kernels._chain``); the
compiled ``C(q, qd) v`` below, a loop over the links, serves both.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numba import njit
from numpy.typing import ArrayLike

from ..errors import InvalidInputError
from .base import GRAVITY, FloatArray, LinkParams, as_vector, diag, suffix_sum


class PlanarChain:
    """A planar serial chain of revolute joints with relative joint angles.

    Parameters
    ----------
    links : sequence of LinkParams
        Links from the base outwards.
    tip_mass : float, optional
        Point mass at the distal end of the last link (kg).
    base : (2,) array_like, optional
        Position of the first joint (m).
    gravity : float, optional
        Gravity along -y (m/s^2).

    Notes
    -----
    With absolute angles ``theta_a = q_1 + ... + q_a`` the kinetic energy is
    ``1/2 thetad^T (W o cos(theta_a - theta_b) + diag(I)) thetad`` and the
    potential energy ``g sum_a w_a sin(theta_a)``. Since ``theta = L q`` with
    a constant ``L``, ``M(q) = L^T M_theta L``, ``C(q, qd) = L^T C_theta L``
    with ``C_theta_ab = W_ab sin(theta_a - theta_b) thetad_b`` (so that
    ``Mdot - 2C`` is skew-symmetric, Property P2), and ``G(q) = L^T G_theta``.
    """

    def __init__(
        self,
        links: Sequence[LinkParams],
        *,
        tip_mass: float = 0.0,
        base: ArrayLike = (0.0, 0.0),
        gravity: float = GRAVITY,
    ) -> None:
        if len(links) < 1:
            raise InvalidInputError("a chain needs at least one link")
        if not np.isfinite(tip_mass) or tip_mass < 0.0:
            raise InvalidInputError(f"tip_mass must be a finite number >= 0, got {tip_mass!r}")
        self.links = tuple(links)
        self.n = len(self.links)
        self.tip_mass = float(tip_mass)
        self.base = as_vector(base, 2, "base")
        self.gravity = float(gravity)
        n = self.n
        lengths = np.array([link.length for link in self.links])
        lever = np.zeros((n, n))  # lever[k, a]: lever of link k's centre along link a
        for k, link in enumerate(self.links):
            lever[k, :k] = lengths[:k]
            lever[k, k] = link.com
        masses = np.array([link.mass for link in self.links])
        self.lengths = lengths
        self.W = np.einsum("k,ka,kb->ab", masses, lever, lever) + self.tip_mass * np.outer(
            lengths, lengths
        )
        self.w = masses @ lever + self.tip_mass * lengths
        self.inertias = np.array([link.inertia for link in self.links])

    # kinematics ------------------------------------------------------------ #
    @staticmethod
    def absolute(q: FloatArray) -> FloatArray:
        """Absolute link angles ``theta = L q``."""
        return np.cumsum(q, axis=-1)

    def tip(self, q: FloatArray) -> FloatArray:
        """Position of the distal end of the last link, shape ``(..., 2)``."""
        th = self.absolute(q)
        x = self.base[0] + np.sum(self.lengths * np.cos(th), axis=-1)
        y = self.base[1] + np.sum(self.lengths * np.sin(th), axis=-1)
        return np.stack([x, y], axis=-1)

    def tip_jacobian(self, q: FloatArray) -> FloatArray:
        """Jacobian of :meth:`tip` with respect to ``q``, shape ``(..., 2, n)``."""
        th = self.absolute(q)
        jx = -suffix_sum(self.lengths * np.sin(th), axis=-1)
        jy = suffix_sum(self.lengths * np.cos(th), axis=-1)
        return np.stack([jx, jy], axis=-2)

    def tip_jacobian_dot(self, q: FloatArray, qd: FloatArray) -> FloatArray:
        """Time derivative of :meth:`tip_jacobian`, shape ``(..., 2, n)``."""
        th = self.absolute(q)
        thd = self.absolute(qd)
        jx = -suffix_sum(self.lengths * np.cos(th) * thd, axis=-1)
        jy = -suffix_sum(self.lengths * np.sin(th) * thd, axis=-1)
        return np.stack([jx, jy], axis=-2)

    # dynamics (links only, no motors) ------------------------------------- #
    def mass_matrix(self, q: FloatArray) -> FloatArray:
        """Link inertia matrix ``M(q)``, shape ``(..., n, n)``."""
        th = self.absolute(q)
        diff = th[..., :, None] - th[..., None, :]
        m_abs = self.W * np.cos(diff) + diag(self.inertias)
        return suffix_sum(suffix_sum(m_abs, axis=-1), axis=-2)

    def coriolis_matrix(self, q: FloatArray, qd: FloatArray) -> FloatArray:
        """Centrifugal-Coriolis matrix ``C(q, qd)``, shape ``(..., n, n)``."""
        th = self.absolute(q)
        thd = self.absolute(qd)
        diff = th[..., :, None] - th[..., None, :]
        c_abs = self.W * np.sin(diff) * thd[..., None, :]
        return suffix_sum(suffix_sum(c_abs, axis=-1), axis=-2)

    def coriolis_vector(self, q: FloatArray, qd: FloatArray) -> FloatArray:
        """``C(q, qd) qd`` without forming ``C``, shape ``(..., n)``."""
        th = self.absolute(q)
        thd = self.absolute(qd)
        diff = th[..., :, None] - th[..., None, :]
        c_abs = np.sum(self.W * np.sin(diff) * (thd * thd)[..., None, :], axis=-1)
        return suffix_sum(c_abs, axis=-1)

    def gravity_vector(self, q: FloatArray) -> FloatArray:
        """Gravity torques ``G(q)``, shape ``(..., n)``."""
        th = self.absolute(q)
        return suffix_sum(self.gravity * self.w * np.cos(th), axis=-1)

    def potential_energy(self, q: FloatArray) -> FloatArray:
        """Gravitational potential energy (J) relative to ``y = base_y``."""
        return self.gravity * np.sum(self.w * np.sin(self.absolute(q)), axis=-1)


@njit(cache=True, inline="always")
def chain_coriolis_times(W, q, qd, v, out, work, n):  # noqa: ANN001, ANN202, PLR0913
    """``C(q, qd) v`` of a planar chain of ``n`` links: ``L^T C_theta L v``."""
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

