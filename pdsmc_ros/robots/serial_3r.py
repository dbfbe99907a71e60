"""The planar 3R serial arm of Section 4.1.1: numpy model and compiled terms side by side.

Fig. 4.1, Table 4.1 (``config/robots.yaml``): three links in the vertical plane,
a motor (inertia ``J``, viscous damping ``B``) at each joint, Eq. (4.1).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import ArrayLike, NDArray

from ..errors import InvalidInputError, UnreachableError
from ..kernels.options import ALLOCATION_FREE
from .base import FloatArray, Manipulator, RobotParams, as_vector, diag
from .chain import PlanarChain, chain_coriolis_times
from .kernel_math import entry_at
from .registry import robot_params
from .urdf import serial_urdf

SERIAL_3R = 0
"""Code of the compiled form (:mod:`pdsmc_ros.robots.compiled`)."""
N = 3
"""Joints: a constant, so the compiled loops below have known lengths."""

# The flat parameter array of :meth:`Serial3R.pack`, by name
_W = 0  # W of the chain, row-major 3 x 3
_WG = 9  # w of the chain (mass times lever along each link)
_INERTIA = 12
_LENGTH = 15
_J = 18
_B = 21
_G = 24


class Serial3R(Manipulator):
    """Planar 3R serial manipulator of Section 4.1.1 (Fig. 4.1, Table 4.1).

    Parameters
    ----------
    payload : float, optional
        Point mass at the end-effector (kg), Section 4.5.2.
    params : RobotParams, optional
        Structural and motor parameters; Table 4.1 by default.

    Notes
    -----
    The appendix's closed-form inertia matrix (Eqs. 12-17) carries typos
    (docs/THESIS_NOTES.md section 2); the model here is derived from the Lagrangian of the
    chain (see :class:`PlanarChain`) and checked against Pinocchio in the tests.
    Task point: ``(x_ee, y_ee, q_ee)`` with ``q_ee = q1 + q2 + q3``, Eqs. (1)-(3).
    """

    name = "serial_3r"
    n = 3
    task_dim = 3
    joint_names = ("joint1", "joint2", "joint3")
    payload_link = 2
    kernel = SERIAL_3R

    def __init__(self, payload: float = 0.0, *, params: RobotParams | None = None) -> None:
        params = params or robot_params(self.name)
        if len(params.links) != 3:
            raise InvalidInputError(f"serial_3r needs 3 links, got {len(params.links)}")
        super().__init__(payload, params=params)
        self.chain = PlanarChain(params.links, tip_mass=payload, gravity=params.gravity)
        self.lengths = self.chain.lengths

    def pack(self) -> FloatArray:
        """Flat parameters of the compiled form: ``W(9) w(3) I(3) L(3) J(3) B(3) g``."""
        c = self.chain
        parts = [c.W.ravel(), c.w, c.inertias, c.lengths, self.J, self.B, [c.gravity]]
        return np.concatenate([np.asarray(x, dtype=float).ravel() for x in parts])

    def description(self, payload: float | None = None) -> str:
        """The arm's URDF (:func:`pdsmc_ros.robots.urdf.serial_urdf`)."""
        return serial_urdf(self.name, self.params, self.payload if payload is None else payload)

    def _fk(self, q: FloatArray) -> FloatArray:
        xy = self.chain.tip(q)
        return np.concatenate([xy, np.sum(q, axis=-1, keepdims=True)], axis=-1)

    def _ik(self, p: FloatArray) -> FloatArray:
        """Appendix Eqs. (4)-(8), branch ``sin(q2) > 0`` (docs/THESIS_NOTES.md section 3)."""
        l1, l2, l3 = self.lengths
        x, y, pose = p[..., 0], p[..., 1], p[..., 2]
        x3 = x - l3 * np.cos(pose)
        y3 = y - l3 * np.sin(pose)
        c2 = (x3 * x3 + y3 * y3 - l1 * l1 - l2 * l2) / (2.0 * l1 * l2)
        bad = np.abs(c2) > 1.0 + 1e-12
        if np.any(bad):
            first = np.argwhere(np.atleast_1d(bad))[0]
            point = np.atleast_2d(p)[tuple(first)] if p.ndim > 1 else p
            raise UnreachableError(
                f"p = {np.array2string(point, precision=6)} is outside the serial_3r workspace "
                f"(wrist point at distance {np.sqrt(x3 * x3 + y3 * y3).flat[first[-1]]:.6g} m, "
                f"reachable {abs(l1 - l2):.3g}..{l1 + l2:.3g} m)"
            )
        q2 = np.arccos(np.clip(c2, -1.0, 1.0))
        q1 = np.arctan2(y3, x3) - np.arctan2(l2 * np.sin(q2), l1 + l2 * np.cos(q2))
        q1 = np.mod(q1 + np.pi, 2.0 * np.pi) - np.pi
        q3 = pose - q1 - q2
        return np.stack([q1, q2, q3], axis=-1)

    def _jacobian(self, q: FloatArray) -> FloatArray:
        jxy = self.chain.tip_jacobian(q)
        jpose = np.ones(q.shape[:-1] + (1, 3))
        return np.concatenate([jxy, jpose], axis=-2)

    def reachable(self, p: ArrayLike) -> NDArray[np.bool_]:
        p = as_vector(p, 3, "p")
        l1, l2, l3 = self.lengths
        x3 = p[..., 0] - l3 * np.cos(p[..., 2])
        y3 = p[..., 1] - l3 * np.sin(p[..., 2])
        c2 = (x3 * x3 + y3 * y3 - l1 * l1 - l2 * l2) / (2.0 * l1 * l2)
        return np.abs(c2) < 1.0 - 1e-9

    def joint_rates(
        self, q: FloatArray, pd: FloatArray, pdd: FloatArray
    ) -> tuple[FloatArray, FloatArray]:
        jac = self._jacobian(q)
        qd = np.linalg.solve(jac, pd[..., None])[..., 0]
        rhs = pdd - np.einsum("...ij,...j->...i", self.jacobian_dot(q, qd), qd)
        return qd, np.linalg.solve(jac, rhs[..., None])[..., 0]

    def jacobian_dot(self, q: FloatArray, qd: FloatArray) -> FloatArray:
        """Time derivative of the task Jacobian, shape ``(..., 3, 3)``."""
        jxy = self.chain.tip_jacobian_dot(q, qd)
        return np.concatenate([jxy, np.zeros(q.shape[:-1] + (1, 3))], axis=-2)

    def _mass_matrix(self, q: FloatArray) -> FloatArray:
        return self.chain.mass_matrix(q) + diag(self.J)

    def _coriolis_matrix(self, q: FloatArray, qd: FloatArray) -> FloatArray:
        return self.chain.coriolis_matrix(q, qd)

    def _coriolis_vector(self, q: FloatArray, qd: FloatArray) -> FloatArray:
        return self.chain.coriolis_vector(q, qd)

    def _gravity(self, q: FloatArray) -> FloatArray:
        return self.chain.gravity_vector(q)

    def _potential(self, q: FloatArray) -> FloatArray:
        return self.chain.potential_energy(q)


# --------------------------------------------------------------------------- #
# Compiled form (one state; scratch from ``work``)
# --------------------------------------------------------------------------- #
@njit(cache=True, inline="always")
def _terms(p, q0, q1, q2, w0, w1, w2):  # noqa: ANN001, ANN202, PLR0913, PLR0915
    """``Mbar = M + J`` (upper triangle, row by row) and ``C qd + G``: nine floats.

    :class:`PlanarChain`'s terms written out for three links, in scalars so a
    closed loop keeps them in registers: absolute angles ``theta = L q``, then
    ``W o cos(theta_a - theta_b) + diag(I)`` and ``C_theta thetad + G_theta``,
    then the suffix sums of ``L^T (.) L``.
    """
    g = p[_G]
    a0 = q0
    a1 = a0 + q1
    a2 = a1 + q2
    d0 = w0
    d1 = d0 + w1
    d2 = d1 + w2
    c0 = math.cos(a0)
    s0 = math.sin(a0)
    c1 = math.cos(a1)
    s1 = math.sin(a1)
    c2 = math.cos(a2)
    s2 = math.sin(a2)
    m00 = p[_W] * (c0 * c0 + s0 * s0) + p[_INERTIA]
    m01 = p[_W + 1] * (c0 * c1 + s0 * s1)
    m02 = p[_W + 2] * (c0 * c2 + s0 * s2)
    m10 = p[_W + 3] * (c1 * c0 + s1 * s0)
    m11 = p[_W + 4] * (c1 * c1 + s1 * s1) + p[_INERTIA + 1]
    m12 = p[_W + 5] * (c1 * c2 + s1 * s2)
    m20 = p[_W + 6] * (c2 * c0 + s2 * s0)
    m21 = p[_W + 7] * (c2 * c1 + s2 * s1)
    m22 = p[_W + 8] * (c2 * c2 + s2 * s2) + p[_INERTIA + 2]
    y0 = g * p[_WG] * c0
    y0 += p[_W] * (s0 * c0 - c0 * s0) * d0 * d0
    y0 += p[_W + 1] * (s0 * c1 - c0 * s1) * d1 * d1
    y0 += p[_W + 2] * (s0 * c2 - c0 * s2) * d2 * d2
    y1 = g * p[_WG + 1] * c1
    y1 += p[_W + 3] * (s1 * c0 - c1 * s0) * d0 * d0
    y1 += p[_W + 4] * (s1 * c1 - c1 * s1) * d1 * d1
    y1 += p[_W + 5] * (s1 * c2 - c1 * s2) * d2 * d2
    y2 = g * p[_WG + 2] * c2
    y2 += p[_W + 6] * (s2 * c0 - c2 * s0) * d0 * d0
    y2 += p[_W + 7] * (s2 * c1 - c2 * s1) * d1 * d1
    y2 += p[_W + 8] * (s2 * c2 - c2 * s2) * d2 * d2
    return (
        0.0 + m00 + m01 + m02 + m10 + m11 + m12 + m20 + m21 + m22 + p[_J],
        0.0 + m01 + m02 + m11 + m12 + m21 + m22,
        0.0 + m02 + m12 + m22,
        0.0 + m11 + m12 + m21 + m22 + p[_J + 1],
        0.0 + m12 + m22,
        0.0 + m22 + p[_J + 2],
        0.0 + y0 + y1 + y2,
        0.0 + y1 + y2,
        0.0 + y2,
    )


@njit(cache=True, inline="always")
def _solve(k00, k01, k02, k11, k12, k22, r0, r1, r2):  # noqa: ANN001, ANN202, PLR0913
    """``Mbar x = r`` for the symmetric 3 x 3 of :func:`_terms` (Cholesky in scalars): ``x`` as three floats."""
    l00 = math.sqrt(k00)
    l10 = k01 / l00
    l11 = math.sqrt(k11 - l10 * l10)
    l20 = k02 / l00
    l21 = (k12 - l20 * l10) / l11
    l22 = math.sqrt(k22 - l20 * l20 - l21 * l21)
    z0 = r0 / l00
    z1 = (r1 - l10 * z0) / l11
    z2 = (r2 - l20 * z0 - l21 * z1) / l22
    x2 = z2 / l22
    x1 = (z1 - l21 * x2) / l11
    x0 = (z0 - l10 * x1 - l20 * x2) / l00
    return x0, x1, x2


@njit(**ALLOCATION_FREE)
def terms(p, q, qd, mass, bias, work):  # noqa: ANN001, ANN201, ARG001
    """``Mbar = M + J`` and ``C qd + G``."""
    k00, k01, k02, k11, k12, k22, b0, b1, b2 = _terms(p, q[0], q[1], q[2], qd[0], qd[1], qd[2])
    mass[0, 0] = k00
    mass[0, 1] = mass[1, 0] = k01
    mass[0, 2] = mass[2, 0] = k02
    mass[1, 1] = k11
    mass[1, 2] = mass[2, 1] = k12
    mass[2, 2] = k22
    bias[0] = b0
    bias[1] = b1
    bias[2] = b2


@njit(cache=True, inline="always")
def accelerations(p, q, qd, tau, out, work):  # noqa: ANN001, ANN201, ARG001
    """Eq. (4.1), ``qdd = Mbar^{-1} (tau - C qd - B qd - G)``, into ``out``: Cholesky in scalars."""
    k00, k01, k02, k11, k12, k22, b0, b1, b2 = _terms(p, q[0], q[1], q[2], qd[0], qd[1], qd[2])
    out[0], out[1], out[2] = _solve(k00, k01, k02, k11, k12, k22, tau[0] - b0 - p[_B] * qd[0],
                                    tau[1] - b1 - p[_B + 1] * qd[1], tau[2] - b2 - p[_B + 2] * qd[2])


@njit(**ALLOCATION_FREE)
def coriolis_times(p, q, qd, v, out, work):  # noqa: ANN001, ANN201
    """``C(q, qd) v``."""
    chain_coriolis_times(p[_W:_W + 9], q, qd, v, out, work, N)


@njit(**ALLOCATION_FREE)
def gravity(p, q, out, work):  # noqa: ANN001, ANN201, ARG001
    """``G(q)``."""
    acc = 0.0
    for i in range(3):
        out[i] = 0.0
    for a in range(3):
        acc += q[a]
        ya = p[_G] * p[_WG + a] * math.cos(acc)
        for i in range(a + 1):
            out[i] += ya


motor_inertia = entry_at(_J)
"""Motor inertia ``J_i``: ``(p, i) -> float``."""
damping = entry_at(_B)
"""Motor viscous damping ``B_i``: ``(p, i) -> float``."""


@njit(**ALLOCATION_FREE)
def outputs(p, q, qd, out, work):  # noqa: ANN001, ANN201, ARG001
    """End-effector ``(x, y)`` into ``out[0:2]`` (``PlanarChain.tip``, base at the origin)."""
    acc = 0.0
    x = 0.0
    y = 0.0
    for a in range(3):
        acc += q[a]
        x += p[_LENGTH + a] * math.cos(acc)
        y += p[_LENGTH + a] * math.sin(acc)
    out[0] = x
    out[1] = y
