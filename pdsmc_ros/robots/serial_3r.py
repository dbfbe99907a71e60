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
from .base import FloatArray, Manipulator, RobotParams, as_vector, diag
from .chain import PlanarChain, chain_coriolis_times, chain_mass_bias
from .registry import register_robot, robot_params

SERIAL_3R = 0
"""Code of the compiled form (:mod:`pdsmc_ros.robots.compiled`)."""

# The flat parameter array of :meth:`Serial3R.pack`, by name
_W = 0  # W of the chain, row-major 3 x 3
_WG = 9  # w of the chain (mass times lever along each link)
_INERTIA = 12
_LENGTH = 15
_J = 18
_B = 21
_G = 24


@register_robot
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
    (NOTES.md section 2); the model here is derived from the Lagrangian of the
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

    def _fk(self, q: FloatArray) -> FloatArray:
        xy = self.chain.tip(q)
        return np.concatenate([xy, np.sum(q, axis=-1, keepdims=True)], axis=-1)

    def _ik(self, p: FloatArray) -> FloatArray:
        """Appendix Eqs. (4)-(8), branch ``sin(q2) > 0`` (NOTES.md section 3)."""
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
@njit(cache=True)
def terms(p, q, qd, mass, bias, work):  # noqa: ANN001, ANN201
    """``Mbar = M + J`` and ``C qd + G``."""
    chain_mass_bias(p[_W:_W + 9], p[_WG:_WG + 3], p[_INERTIA:_INERTIA + 3], p[_G], q, qd, mass, bias, work)
    for i in range(3):
        mass[i, i] += p[_J + i]


@njit(cache=True)
def coriolis_times(p, q, qd, v, out, work):  # noqa: ANN001, ANN201
    """``C(q, qd) v``."""
    chain_coriolis_times(p[_W:_W + 9], q, qd, v, out, work)


@njit(cache=True)
def gravity(p, q, out):  # noqa: ANN001, ANN201
    """``G(q)``."""
    acc = 0.0
    for i in range(3):
        out[i] = 0.0
    for a in range(3):
        acc += q[a]
        ya = p[_G] * p[_WG + a] * math.cos(acc)
        for i in range(a + 1):
            out[i] += ya


@njit(cache=True)
def motor_inertia(p, i):  # noqa: ANN001, ANN201
    return p[_J + i]


@njit(cache=True)
def damping(p, i):  # noqa: ANN001, ANN201
    return p[_B + i]


@njit(cache=True)
def outputs(p, q, out):  # noqa: ANN001, ANN201
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
