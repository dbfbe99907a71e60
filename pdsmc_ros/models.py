"""Kinematics and dynamics of the thesis manipulators (numpy only).

Two robots from Acob (2015), Section 4.1 and the Appendix:

* :class:`Serial3R` -- the planar 3R serial arm of Table 4.1 with a motor
  (inertia ``J``, viscous damping ``B``) at each joint, Eq. (4.1).
* :class:`Parallel5R` -- the planar five-bar of Table 4.2, driven at its two
  base joints, with the reduced model of Ghorbel (1995), Eqs. (4.2) and
  Appendix Eqs. (47)-(70).

Both move in the vertical plane with gravity along ``-y``. A payload is a point
mass at the end-effector (Section 4.5.2).

Every function accepts a leading batch dimension: ``q`` of shape ``(..., n)``.
Model parameters may carry the same batch dimension (see ``stack``), which is
how the whole thesis matrix is simulated at once.

The building block is :class:`PlanarChain`, a planar serial chain written in
absolute link angles ``theta = L q`` (``L`` lower-triangular ones). In absolute
angles the inertia matrix is ``W o cos(theta_a - theta_b) + diag(I)`` with the
constant ``W_ab = sum_k m_k l_ka l_kb`` (``l_ka`` the lever of link ``k``'s mass
centre along link ``a``), which makes mass matrix, Coriolis and gravity terms a
few vectorised lines, exact for any number of links and any payload.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .errors import InvalidInputError, SingularConfigurationError, UnreachableError

GRAVITY = 9.81
"""Gravitational acceleration (m/s^2), acting along -y."""

FloatArray = NDArray[np.float64]

_SINGULAR_TOL = 1e-9


def as_vector(value: ArrayLike, size: int, name: str) -> FloatArray:
    """Return ``value`` as a float array whose last axis has ``size`` entries.

    Raises
    ------
    InvalidInputError
        If the shape is wrong or any entry is NaN or infinite; the message
        names the argument and shows the value.
    """
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise InvalidInputError(f"{name} must be numeric, got {value!r}") from exc
    if arr.ndim == 0 or arr.shape[-1] != size:
        raise InvalidInputError(
            f"{name} must have {size} entries in its last axis, got shape {arr.shape}: {value!r}"
        )
    if not np.all(np.isfinite(arr)):
        raise InvalidInputError(f"{name} must be finite, got {np.array2string(arr, precision=6)}")
    return arr


def suffix_sum(x: FloatArray, axis: int) -> FloatArray:
    """``out[i] = sum_{a >= i} x[a]`` along ``axis`` (that is ``L^T x``)."""
    flipped = np.flip(x, axis=axis)
    return np.flip(np.cumsum(flipped, axis=axis), axis=axis)


# --------------------------------------------------------------------------- #
# Planar serial chain
# --------------------------------------------------------------------------- #
@dataclass(frozen=True)
class LinkParams:
    """Structural parameters of one link (Tables 4.1 and 4.2).

    Attributes
    ----------
    mass : float
        Link mass (kg).
    length : float
        Joint-to-joint length (m).
    com : float
        Distance of the mass centre from the proximal joint, along the link (m).
    inertia : float
        Moment of inertia about the mass centre (kg m^2).
    """

    mass: float
    length: float
    com: float
    inertia: float

    def __post_init__(self) -> None:
        for name in ("mass", "length", "com", "inertia"):
            value = getattr(self, name)
            if not np.isfinite(value) or value < 0.0:
                raise InvalidInputError(f"link {name} must be a finite number >= 0, got {value!r}")
        if self.length <= 0.0:
            raise InvalidInputError(f"link length must be > 0, got {self.length!r}")


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
        m_abs = self.W * np.cos(diff) + _diag(self.inertias)
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


def _diag(values: FloatArray) -> FloatArray:
    """Diagonal matrices from the last axis of ``values``."""
    return values[..., :, None] * np.eye(values.shape[-1])


# --------------------------------------------------------------------------- #
# Robot parameters
# --------------------------------------------------------------------------- #
@dataclass(frozen=True)
class RobotParams:
    """Structural and motor parameters of a manipulator.

    Attributes
    ----------
    links : tuple of LinkParams
        Links in thesis numbering (Tables 4.1, 4.2).
    motor_inertia, motor_damping : float
        ``J_i`` (kg m^2) and ``B_i`` (N m s) of every actuated joint.
    base_length : float
        ``L5`` of the five-bar (m); unused by the serial arm.
    gravity : float
        Gravity along -y (m/s^2).
    """

    links: tuple[LinkParams, ...]
    motor_inertia: float
    motor_damping: float
    base_length: float = 0.0
    gravity: float = GRAVITY

    @classmethod
    def from_mapping(cls, data: Mapping[str, Any], *, name: str = "robot") -> RobotParams:
        """Build from a YAML-style mapping (see ``config/robots.yaml``)."""
        try:
            links = tuple(
                LinkParams(
                    mass=float(link["mass"]),
                    length=float(link["length"]),
                    com=float(link["com"]),
                    inertia=float(link["inertia"]),
                )
                for link in data["links"]
            )
            return cls(
                links=links,
                motor_inertia=float(data["motor_inertia"]),
                motor_damping=float(data["motor_damping"]),
                base_length=float(data.get("base_length", 0.0)),
                gravity=float(data.get("gravity", GRAVITY)),
            )
        except (KeyError, TypeError, ValueError) as exc:
            raise InvalidInputError(f"{name}: malformed robot parameters ({exc})") from exc


SERIAL_3R_PARAMS = RobotParams(
    links=(
        LinkParams(mass=1.00, length=0.50, com=0.25, inertia=0.10),
        LinkParams(mass=1.00, length=0.50, com=0.25, inertia=0.10),
        LinkParams(mass=0.50, length=0.30, com=0.15, inertia=0.05),
    ),
    motor_inertia=0.05,
    motor_damping=0.07,
)
"""Table 4.1 (4th column: inertia about the mass centre) and Section 4.1.1."""

PARALLEL_5R_PARAMS = RobotParams(
    links=(
        LinkParams(mass=0.91, length=0.080, com=0.006, inertia=0.847e-2),
        LinkParams(mass=0.28, length=0.100, com=0.028, inertia=0.630e-2),
        LinkParams(mass=0.38, length=0.250, com=0.125, inertia=4.002e-2),
        LinkParams(mass=0.38, length=0.250, com=0.125, inertia=4.002e-2),
    ),
    motor_inertia=0.05,
    motor_damping=0.05,
    base_length=0.250,
)
"""Table 4.2 and Section 4.1.2 (links 1, 2 driven; link 5 is the base)."""


# --------------------------------------------------------------------------- #
# Common robot interface
# --------------------------------------------------------------------------- #
class Manipulator:
    """Interface shared by :class:`Serial3R` and :class:`Parallel5R`.

    Subclasses set ``name``, ``n`` (actuated joints), ``task_dim`` (size of the
    task point given to :meth:`inverse_kinematics`), ``joint_names`` and
    implement the underscored, unchecked methods. The public methods validate
    their input and delegate.
    """

    name: str = ""
    n: int = 0
    task_dim: int = 0
    joint_names: tuple[str, ...] = ()
    passive_joint_names: tuple[str, ...] = ()
    J: FloatArray
    B: FloatArray

    # -- checked public API -------------------------------------------------- #
    def forward_kinematics(self, q: ArrayLike) -> FloatArray:
        """Task point of configuration ``q`` (serial: x, y, pose; parallel: x, y)."""
        return self._fk(as_vector(q, self.n, "q"))

    def inverse_kinematics(self, p: ArrayLike) -> FloatArray:
        """Actuated joint angles that place the end-effector at ``p``."""
        return self._ik(as_vector(p, self.task_dim, "p"))

    def jacobian(self, q: ArrayLike) -> FloatArray:
        """Task Jacobian ``d p / d q``, shape ``(..., task_dim, n)``."""
        return self._jacobian(as_vector(q, self.n, "q"))

    def mass_matrix(self, q: ArrayLike) -> FloatArray:
        """``Mbar(q) = M(q) + J`` (motor inertia included), Eq. (4.1)."""
        return self._mass_matrix(as_vector(q, self.n, "q"))

    def coriolis_matrix(self, q: ArrayLike, qd: ArrayLike) -> FloatArray:
        """Centrifugal-Coriolis matrix ``C(q, qd)``."""
        return self._coriolis_matrix(as_vector(q, self.n, "q"), as_vector(qd, self.n, "qd"))

    def gravity(self, q: ArrayLike) -> FloatArray:
        """Gravity vector ``G(q)``."""
        return self._gravity(as_vector(q, self.n, "q"))

    def forward_dynamics(self, q: ArrayLike, qd: ArrayLike, tau: ArrayLike) -> FloatArray:
        """Joint accelerations of Eq. (4.1): ``Mbar qdd + C qd + B qd + G = tau``."""
        return self._forward_dynamics(
            as_vector(q, self.n, "q"), as_vector(qd, self.n, "qd"), as_vector(tau, self.n, "tau")
        )

    def inverse_dynamics(self, q: ArrayLike, qd: ArrayLike, qdd: ArrayLike) -> FloatArray:
        """Torque of Eq. (4.1) that produces ``qdd`` at ``(q, qd)``:
        ``tau = Mbar qdd + C qd + G + B qd`` (the inverse of :meth:`forward_dynamics`)."""
        q = as_vector(q, self.n, "q")
        qd = as_vector(qd, self.n, "qd")
        qdd = as_vector(qdd, self.n, "qdd")
        m, bias = self._bias(q, qd)
        return np.einsum("...ij,...j->...i", m, qdd) + bias + self.B * qd

    def total_energy(self, q: ArrayLike, qd: ArrayLike) -> FloatArray:
        """Kinetic (links and motors) plus potential energy (J)."""
        q = as_vector(q, self.n, "q")
        qd = as_vector(qd, self.n, "qd")
        m = self._mass_matrix(q)
        kinetic = 0.5 * np.einsum("...i,...ij,...j->...", qd, m, qd)
        return kinetic + self._potential(q)

    def position(self, q: FloatArray) -> FloatArray:
        """End-effector (x, y), shape ``(..., 2)`` (unchecked, for hot paths)."""
        return self._fk(q)[..., :2]

    def reachable(self, p: ArrayLike) -> NDArray[np.bool_]:
        """Whether each task point of ``p`` (shape ``(..., task_dim)``) can be reached."""
        raise NotImplementedError

    def joint_rates(
        self, q: FloatArray, pd: FloatArray, pdd: FloatArray
    ) -> tuple[FloatArray, FloatArray]:
        """Joint rates and accelerations that realise task rates ``pd``, ``pdd``.

        Solves ``J qd = pd`` and ``J qdd = pdd - Jdot qd`` (never an explicit inverse).
        """
        raise NotImplementedError

    # -- unchecked implementation -------------------------------------------- #
    def _fk(self, q: FloatArray) -> FloatArray:
        raise NotImplementedError

    def _ik(self, p: FloatArray) -> FloatArray:
        raise NotImplementedError

    def _jacobian(self, q: FloatArray) -> FloatArray:
        raise NotImplementedError

    def _mass_matrix(self, q: FloatArray) -> FloatArray:
        raise NotImplementedError

    def _coriolis_matrix(self, q: FloatArray, qd: FloatArray) -> FloatArray:
        raise NotImplementedError

    def _coriolis_vector(self, q: FloatArray, qd: FloatArray) -> FloatArray:
        return np.einsum("...ij,...j->...i", self._coriolis_matrix(q, qd), qd)

    def _gravity(self, q: FloatArray) -> FloatArray:
        raise NotImplementedError

    def _potential(self, q: FloatArray) -> FloatArray:
        raise NotImplementedError

    def _bias(self, q: FloatArray, qd: FloatArray) -> tuple[FloatArray, FloatArray]:
        """``(Mbar(q), C(q, qd) qd + G(q))`` sharing intermediate results."""
        return self._mass_matrix(q), self._coriolis_vector(q, qd) + self._gravity(q)

    def _forward_dynamics(self, q: FloatArray, qd: FloatArray, tau: FloatArray) -> FloatArray:
        m, bias = self._bias(q, qd)
        rhs = tau - bias - self.B * qd
        return np.linalg.solve(m, rhs[..., None])[..., 0]

    def passive_joints(self, q: FloatArray, qd: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Angles and rates of unactuated joints (none for a serial arm)."""
        shape = q.shape[:-1] + (0,)
        return np.zeros(shape), np.zeros(shape)


def _motor_array(value: float | FloatArray, n: int) -> FloatArray:
    return np.asarray(value, dtype=float)[..., None] * np.ones(n)


# --------------------------------------------------------------------------- #
# Serial 3R
# --------------------------------------------------------------------------- #
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

    def __init__(self, payload: float = 0.0, *, params: RobotParams = SERIAL_3R_PARAMS) -> None:
        if len(params.links) != 3:
            raise InvalidInputError(f"serial_3r needs 3 links, got {len(params.links)}")
        self.params = params
        self.payload = float(payload)
        self.chain = PlanarChain(params.links, tip_mass=payload, gravity=params.gravity)
        self.J = _motor_array(params.motor_inertia, 3)
        self.B = _motor_array(params.motor_damping, 3)
        self.lengths = self.chain.lengths

    def with_payload(self, payload: float) -> Serial3R:
        """The same arm carrying ``payload`` kg at the end-effector."""
        return Serial3R(payload, params=self.params)

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
        return self.chain.mass_matrix(q) + _diag(self.J)

    def _coriolis_matrix(self, q: FloatArray, qd: FloatArray) -> FloatArray:
        return self.chain.coriolis_matrix(q, qd)

    def _coriolis_vector(self, q: FloatArray, qd: FloatArray) -> FloatArray:
        return self.chain.coriolis_vector(q, qd)

    def _gravity(self, q: FloatArray) -> FloatArray:
        return self.chain.gravity_vector(q)

    def _potential(self, q: FloatArray) -> FloatArray:
        return self.chain.potential_energy(q)


# --------------------------------------------------------------------------- #
# Parallel 5R
# --------------------------------------------------------------------------- #
@dataclass
class FiveBarState:
    """Open-tree coordinates of the five-bar: ``q' = (q1, q2, q3, q4)``.

    ``rho`` maps actuated rates to open-tree rates (Appendix Eq. 56), stored as
    the two chains' rows: ``rho_left`` rows (q1, q3), ``rho_right`` rows (q2, q4).
    """

    q_left: FloatArray
    q_right: FloatArray
    rho_left: FloatArray
    rho_right: FloatArray
    constraint_passive: FloatArray = field(repr=False)


class Parallel5R(Manipulator):
    """Planar five-bar (parallel 5R) manipulator of Section 4.1.2 (Fig. 4.2, Table 4.2).

    Actuated joints ``q1`` at ``O1 = (0, 0)`` and ``q2`` at ``O2 = (L5, 0)``;
    the left chain is links 1 and 3 (relative angle ``q3``), the right chain
    links 2 and 4 (relative angle ``q4``); the end-effector is the common
    distal joint. Dynamics: the reduced model of Eqs. (4.2) and (56)-(70),
    ``M = rho^T M' rho + J``, ``C = rho^T C' rho + rho^T M' rhodot``,
    ``G = rho^T G'``.

    Parameters
    ----------
    payload : float, optional
        Point mass at the end-effector (kg), carried by the left chain's tip.
    params : RobotParams, optional
        Table 4.2 by default.
    assembly_mode : {+1, -1}, optional
        Side of the line ``A1 A2`` (the two elbows) on which the end-effector
        lies; ``+1`` (left of ``A1 -> A2``) is the thesis configuration. Kept
        constant along a motion so the passive joints stay continuous.
    left_elbow, right_elbow : {+1, -1}, optional
        Sign of ``q3`` and ``q4`` chosen by :meth:`inverse_kinematics`; the
        defaults (-1, +1) reproduce Table 4.6 (NOTES.md section 3).
    """

    name = "parallel_5r"
    n = 2
    task_dim = 2
    joint_names = ("joint1", "joint2")
    passive_joint_names = ("joint3", "joint4")

    def __init__(
        self,
        payload: float = 0.0,
        *,
        params: RobotParams = PARALLEL_5R_PARAMS,
        assembly_mode: int = 1,
        left_elbow: int = -1,
        right_elbow: int = 1,
    ) -> None:
        if len(params.links) != 4:
            raise InvalidInputError(f"parallel_5r needs 4 links, got {len(params.links)}")
        for name, value in (
            ("assembly_mode", assembly_mode),
            ("left_elbow", left_elbow),
            ("right_elbow", right_elbow),
        ):
            if value not in (1, -1):
                raise InvalidInputError(f"{name} must be +1 or -1, got {value!r}")
        if params.base_length <= 0.0:
            raise InvalidInputError(f"base_length must be > 0, got {params.base_length!r}")
        self.params = params
        self.payload = float(payload)
        self.assembly_mode = assembly_mode
        self.left_elbow = left_elbow
        self.right_elbow = right_elbow
        l1, l2, l3, l4 = params.links
        self.left = PlanarChain((l1, l3), tip_mass=payload, gravity=params.gravity)
        self.right = PlanarChain(
            (l2, l4), base=(params.base_length, 0.0), gravity=params.gravity
        )
        self.L1, self.L2, self.L3, self.L4 = (link.length for link in params.links)
        self.L5 = params.base_length
        self.J = _motor_array(params.motor_inertia, 2)
        self.B = _motor_array(params.motor_damping, 2)

    def with_payload(self, payload: float) -> Parallel5R:
        """The same mechanism carrying ``payload`` kg at the end-effector."""
        return Parallel5R(
            payload,
            params=self.params,
            assembly_mode=self.assembly_mode,
            left_elbow=self.left_elbow,
            right_elbow=self.right_elbow,
        )

    # -- position analysis --------------------------------------------------- #
    def _elbows(self, q: FloatArray) -> tuple[FloatArray, FloatArray]:
        a1 = np.stack([self.L1 * np.cos(q[..., 0]), self.L1 * np.sin(q[..., 0])], axis=-1)
        a2 = np.stack(
            [self.L5 + self.L2 * np.cos(q[..., 1]), self.L2 * np.sin(q[..., 1])], axis=-1
        )
        return a1, a2

    def _end_effector(self, q: FloatArray, *, check: bool = False) -> FloatArray:
        """Forward position (Appendix Eqs. 26-34) as a circle intersection."""
        a1, a2 = self._elbows(q)
        u = a2 - a1
        d2 = np.sum(u * u, axis=-1)
        d = np.sqrt(d2)
        along = (d2 + self.L3**2 - self.L4**2) / (2.0 * d)
        h2 = self.L3**2 - along * along
        if check and np.any(h2 <= _SINGULAR_TOL * self.L3**2):
            raise SingularConfigurationError(
                f"q = {np.array2string(np.asarray(q), precision=6)}: the five-bar cannot "
                "assemble there or is at a forward singularity (links 3 and 4 aligned)"
            )
        h = np.sqrt(np.maximum(h2, 0.0))
        unit = u / d[..., None]
        normal = np.stack([-unit[..., 1], unit[..., 0]], axis=-1)
        return a1 + along[..., None] * unit + (self.assembly_mode * h)[..., None] * normal

    def open_tree(self, q: FloatArray, *, check: bool = False) -> tuple[FloatArray, FloatArray]:
        """Joint angles of both chains: ``(q1, q3)`` and ``(q2, q4)``, q3/q4 in (-pi, pi]."""
        a1, a2 = self._elbows(q)
        p = self._end_effector(q, check=check)
        th3 = np.arctan2(p[..., 1] - a1[..., 1], p[..., 0] - a1[..., 0])
        th4 = np.arctan2(p[..., 1] - a2[..., 1], p[..., 0] - a2[..., 0])
        q3 = _wrap(th3 - q[..., 0])
        q4 = _wrap(th4 - q[..., 1])
        return (
            np.stack([q[..., 0], q3], axis=-1),
            np.stack([q[..., 1], q4], axis=-1),
        )

    def state(self, q: FloatArray, *, check: bool = False) -> FiveBarState:
        """Open-tree angles and ``rho`` (Eq. 56) via the loop-closure Jacobian."""
        q_left, q_right = self.open_tree(q, check=check)
        j_left = self.left.tip_jacobian(q_left)  # d tip / d (q1, q3)
        j_right = self.right.tip_jacobian(q_right)  # d tip / d (q2, q4)
        # Constraint phi = tip_left - tip_right = 0 (Eqs. 47-55):
        # [j_left[:,0], -j_right[:,0]] qd_act + [j_left[:,1], -j_right[:,1]] qd_pas = 0
        a_act = np.stack([j_left[..., :, 0], -j_right[..., :, 0]], axis=-1)
        a_pas = np.stack([j_left[..., :, 1], -j_right[..., :, 1]], axis=-1)
        if check:
            det = np.linalg.det(a_pas)
            if np.any(np.abs(det) < _SINGULAR_TOL):
                raise SingularConfigurationError(
                    f"q = {np.array2string(np.asarray(q), precision=6)}: loop-closure Jacobian "
                    "is singular (forward singularity of the five-bar)"
                )
        r = -np.linalg.solve(a_pas, a_act)  # d(q3, q4)/d(q1, q2)
        eye_rows = np.broadcast_to(np.eye(2), r.shape)
        rho_left = np.stack([eye_rows[..., 0, :], r[..., 0, :]], axis=-2)
        rho_right = np.stack([eye_rows[..., 1, :], r[..., 1, :]], axis=-2)
        return FiveBarState(q_left, q_right, rho_left, rho_right, a_pas)

    def _rho_dot_qd(self, st: FiveBarState, qd: FloatArray) -> tuple[FloatArray, FloatArray]:
        """``rhodot qd`` for both chains (Eq. 57), from ``A_pas Rdot = -Adot rho``."""
        qd_left = np.einsum("...ij,...j->...i", st.rho_left, qd)
        qd_right = np.einsum("...ij,...j->...i", st.rho_right, qd)
        # d/dt of the constraint Jacobian applied to qd' equals J_dot qd' per chain
        acc_left = np.einsum(
            "...ij,...j->...i", self.left.tip_jacobian_dot(st.q_left, qd_left), qd_left
        )
        acc_right = np.einsum(
            "...ij,...j->...i", self.right.tip_jacobian_dot(st.q_right, qd_right), qd_right
        )
        pas_dd = -np.linalg.solve(st.constraint_passive, (acc_left - acc_right)[..., None])[
            ..., 0
        ]
        zeros = np.zeros(qd.shape[:-1])
        return (
            np.stack([zeros, pas_dd[..., 0]], axis=-1),
            np.stack([zeros, pas_dd[..., 1]], axis=-1),
        )

    def passive_joints(self, q: FloatArray, qd: FloatArray) -> tuple[FloatArray, FloatArray]:
        """``(q3, q4)`` and their rates for actuated ``q``, ``qd``."""
        st = self.state(q)
        qd_left = np.einsum("...ij,...j->...i", st.rho_left, qd)
        qd_right = np.einsum("...ij,...j->...i", st.rho_right, qd)
        return (
            np.stack([st.q_left[..., 1], st.q_right[..., 1]], axis=-1),
            np.stack([qd_left[..., 1], qd_right[..., 1]], axis=-1),
        )

    def _fk(self, q: FloatArray) -> FloatArray:
        return self._end_effector(q, check=True)

    def position(self, q: FloatArray) -> FloatArray:
        return self._end_effector(q)

    def _ik(self, p: FloatArray) -> FloatArray:
        """Two 2R inverse problems (Appendix Eqs. 35-42) with the thesis branches."""
        q1, _ = _two_link_ik(p, np.zeros(2), self.L1, self.L3, self.left_elbow, "left (O1)", p)
        q2, _ = _two_link_ik(
            p, np.array([self.L5, 0.0]), self.L2, self.L4, self.right_elbow, "right (O2)", p
        )
        return np.stack([_wrap(q1), _wrap(q2)], axis=-1)

    def chain_ik(self, p: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Open-tree angles ``(q1, q3)`` and ``(q2, q4)`` for end-effector ``p``."""
        q1, q3 = _two_link_ik(p, np.zeros(2), self.L1, self.L3, self.left_elbow, "left (O1)", p)
        q2, q4 = _two_link_ik(
            p, np.array([self.L5, 0.0]), self.L2, self.L4, self.right_elbow, "right (O2)", p
        )
        return np.stack([q1, q3], axis=-1), np.stack([q2, q4], axis=-1)

    def reachable(self, p: ArrayLike) -> NDArray[np.bool_]:
        p = as_vector(p, 2, "p")
        ok = np.ones(p.shape[:-1], dtype=bool)
        for base, a, b in (((0.0, 0.0), self.L1, self.L3), ((self.L5, 0.0), self.L2, self.L4)):
            d2 = (p[..., 0] - base[0]) ** 2 + (p[..., 1] - base[1]) ** 2
            c = (d2 - a * a - b * b) / (2.0 * a * b)
            ok &= np.abs(c) < 1.0 - 1e-9
        return ok

    def joint_rates(
        self, q: FloatArray, pd: FloatArray, pdd: FloatArray
    ) -> tuple[FloatArray, FloatArray]:
        rates = []
        accels = []
        for chain, angles in zip((self.left, self.right), self.open_tree(q), strict=True):
            jac = chain.tip_jacobian(angles)
            rate = np.linalg.solve(jac, pd[..., None])[..., 0]
            rhs = pdd - np.einsum("...ij,...j->...i", chain.tip_jacobian_dot(angles, rate), rate)
            rates.append(rate[..., 0])
            accels.append(np.linalg.solve(jac, rhs[..., None])[..., 0][..., 0])
        return np.stack(rates, axis=-1), np.stack(accels, axis=-1)

    def _jacobian(self, q: FloatArray) -> FloatArray:
        st = self.state(q, check=True)
        return np.einsum("...ij,...jk->...ik", self.left.tip_jacobian(st.q_left), st.rho_left)

    # -- dynamics ------------------------------------------------------------ #
    def _mass_matrix(self, q: FloatArray) -> FloatArray:
        st = self.state(q)
        return self._reduced_mass(st)

    def _reduced_mass(self, st: FiveBarState) -> FloatArray:
        m_left = self.left.mass_matrix(st.q_left)
        m_right = self.right.mass_matrix(st.q_right)
        return (
            _congruence(st.rho_left, m_left) + _congruence(st.rho_right, m_right) + _diag(self.J)
        )

    def _coriolis_matrix(self, q: FloatArray, qd: FloatArray) -> FloatArray:
        st = self.state(q)
        qd_left = np.einsum("...ij,...j->...i", st.rho_left, qd)
        qd_right = np.einsum("...ij,...j->...i", st.rho_right, qd)
        rho_dot_left, rho_dot_right = self._rho_dot_matrices(st, qd)
        out = _congruence(st.rho_left, self.left.coriolis_matrix(st.q_left, qd_left))
        out = out + _congruence(st.rho_right, self.right.coriolis_matrix(st.q_right, qd_right))
        out = out + np.einsum(
            "...ji,...jk,...kl->...il", st.rho_left, self.left.mass_matrix(st.q_left), rho_dot_left
        )
        return out + np.einsum(
            "...ji,...jk,...kl->...il",
            st.rho_right,
            self.right.mass_matrix(st.q_right),
            rho_dot_right,
        )

    def _rho_dot_matrices(self, st: FiveBarState, qd: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Full ``rhodot`` (Eq. 57), columns from unit actuated rates (linear in qd)."""
        qd_left = np.einsum("...ij,...j->...i", st.rho_left, qd)
        qd_right = np.einsum("...ij,...j->...i", st.rho_right, qd)
        jd_left = self.left.tip_jacobian_dot(st.q_left, qd_left)
        jd_right = self.right.tip_jacobian_dot(st.q_right, qd_right)
        # Adot rho, column k: (Jdot_left rho_left[:, k]) - (Jdot_right rho_right[:, k])
        adot_rho = np.einsum("...ij,...jk->...ik", jd_left, st.rho_left) - np.einsum(
            "...ij,...jk->...ik", jd_right, st.rho_right
        )
        r_dot = -np.linalg.solve(st.constraint_passive, adot_rho)
        zeros = np.zeros_like(r_dot[..., 0, :])
        return (
            np.stack([zeros, r_dot[..., 0, :]], axis=-2),
            np.stack([zeros, r_dot[..., 1, :]], axis=-2),
        )

    def _gravity(self, q: FloatArray) -> FloatArray:
        st = self.state(q)
        return self._reduced_gravity(st)

    def _reduced_gravity(self, st: FiveBarState) -> FloatArray:
        g_left = self.left.gravity_vector(st.q_left)
        g_right = self.right.gravity_vector(st.q_right)
        return np.einsum("...ji,...j->...i", st.rho_left, g_left) + np.einsum(
            "...ji,...j->...i", st.rho_right, g_right
        )

    def _bias(self, q: FloatArray, qd: FloatArray) -> tuple[FloatArray, FloatArray]:
        st = self.state(q)
        qd_left = np.einsum("...ij,...j->...i", st.rho_left, qd)
        qd_right = np.einsum("...ij,...j->...i", st.rho_right, qd)
        m_left = self.left.mass_matrix(st.q_left)
        m_right = self.right.mass_matrix(st.q_right)
        rdq_left, rdq_right = self._rho_dot_qd(st, qd)
        # rho^T (C' qd' + M' rhodot qd + G') per chain
        f_left = (
            self.left.coriolis_vector(st.q_left, qd_left)
            + np.einsum("...ij,...j->...i", m_left, rdq_left)
            + self.left.gravity_vector(st.q_left)
        )
        f_right = (
            self.right.coriolis_vector(st.q_right, qd_right)
            + np.einsum("...ij,...j->...i", m_right, rdq_right)
            + self.right.gravity_vector(st.q_right)
        )
        bias = np.einsum("...ji,...j->...i", st.rho_left, f_left) + np.einsum(
            "...ji,...j->...i", st.rho_right, f_right
        )
        mass = (
            _congruence(st.rho_left, m_left) + _congruence(st.rho_right, m_right) + _diag(self.J)
        )
        return mass, bias

    def _potential(self, q: FloatArray) -> FloatArray:
        q_left, q_right = self.open_tree(q)
        return self.left.potential_energy(q_left) + self.right.potential_energy(q_right)


def _congruence(rho: FloatArray, m: FloatArray) -> FloatArray:
    """``rho^T m rho``."""
    return np.einsum("...ji,...jk,...kl->...il", rho, m, rho)


def _wrap(angle: FloatArray) -> FloatArray:
    """Wrap to (-pi, pi]."""
    return np.pi - np.mod(np.pi - angle, 2.0 * np.pi)


def _two_link_ik(
    p: FloatArray,
    base: FloatArray,
    a: float,
    b: float,
    elbow: int,
    label: str,
    original: FloatArray,
) -> tuple[FloatArray, FloatArray]:
    """Base and elbow angles of a 2R chain (lengths ``a``, ``b``) reaching ``p``."""
    dx = p[..., 0] - base[0]
    dy = p[..., 1] - base[1]
    d2 = dx * dx + dy * dy
    c = (d2 - a * a - b * b) / (2.0 * a * b)
    bad = np.abs(c) > 1.0 - 1e-12
    if np.any(bad):
        idx = np.argwhere(np.atleast_1d(bad))[0][0]
        point = np.atleast_2d(original)[idx]
        dist = np.sqrt(np.atleast_1d(d2)[idx])
        raise UnreachableError(
            f"p = {np.array2string(point, precision=6)} is outside the parallel_5r workspace: "
            f"the {label} chain reaches {abs(a - b):.4g}..{a + b:.4g} m, the point is "
            f"{dist:.4g} m away (or at a chain's boundary singularity)"
        )
    elbow_angle = elbow * np.arccos(c)
    base_angle = np.arctan2(dy, dx) - np.arctan2(
        b * np.sin(elbow_angle), a + b * np.cos(elbow_angle)
    )
    return base_angle, elbow_angle


# --------------------------------------------------------------------------- #
# Construction helpers
# --------------------------------------------------------------------------- #
ROBOTS: dict[str, type[Manipulator]] = {"serial_3r": Serial3R, "parallel_5r": Parallel5R}


def make_robot(
    name: str, *, payload: float = 0.0, params: RobotParams | None = None
) -> Manipulator:
    """Build a robot by name (``serial_3r`` or ``parallel_5r``)."""
    if name == "serial_3r":
        return Serial3R(payload, params=params or SERIAL_3R_PARAMS)
    if name == "parallel_5r":
        return Parallel5R(payload, params=params or PARALLEL_5R_PARAMS)
    raise InvalidInputError(f"unknown robot {name!r}; choose one of: {', '.join(ROBOTS)}")


__all__ = [
    "GRAVITY",
    "LinkParams",
    "Manipulator",
    "PARALLEL_5R_PARAMS",
    "Parallel5R",
    "PlanarChain",
    "ROBOTS",
    "RobotParams",
    "SERIAL_3R_PARAMS",
    "Serial3R",
    "as_vector",
    "make_robot",
]
