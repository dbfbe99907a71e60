"""What every robot is: its parameters and the :class:`Manipulator` interface (numpy only).

Every function accepts a leading batch dimension: ``q`` of shape ``(..., n)``.
A robot implements the underscored, unchecked methods; the public methods
validate their input and delegate. A robot with a compiled form (numba) also
sets :attr:`Manipulator.kernel` and implements :meth:`Manipulator.pack`; one
without runs on the numpy path (see :mod:`pdsmc_ros.sim`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import InvalidInputError

GRAVITY = 9.81
"""Gravitational acceleration (m/s^2), acting along -y."""

FloatArray = NDArray[np.float64]


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



def diag(values: FloatArray) -> FloatArray:
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
    effort_limit, velocity_limit : tuple of float
        Per actuated joint: the largest torque (N m) and rate (rad/s); empty: unknown (unlimited).
    position_limit : tuple of (float, float)
        Per actuated joint: lower and upper angle (rad); empty: unlimited (the planar arms'
        joints turn freely).
    """

    links: tuple[LinkParams, ...]
    motor_inertia: float
    motor_damping: float
    base_length: float = 0.0
    gravity: float = GRAVITY
    effort_limit: tuple[float, ...] = ()
    velocity_limit: tuple[float, ...] = ()
    position_limit: tuple[tuple[float, float], ...] = ()

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
            limits = data.get("limits") or {}
            return cls(
                links=links,
                motor_inertia=float(data["motor_inertia"]),
                motor_damping=float(data["motor_damping"]),
                base_length=float(data.get("base_length", 0.0)),
                gravity=float(data.get("gravity", GRAVITY)),
                effort_limit=tuple(float(v) for v in limits.get("effort") or ()),
                velocity_limit=tuple(float(v) for v in limits.get("velocity") or ()),
                position_limit=tuple((float(lo), float(hi)) for lo, hi in limits.get("position") or ()),
            )
        except (KeyError, TypeError, ValueError, AttributeError) as exc:
            raise InvalidInputError(f"{name}: malformed robot parameters ({exc})") from exc



# --------------------------------------------------------------------------- #
# Common robot interface
# --------------------------------------------------------------------------- #
class Manipulator:
    """The interface of every robot (the built-in ones: ``Serial3R``, ``Parallel5R``).

    Subclasses set ``name``, ``n`` (actuated joints), ``task_dim`` (size of the
    task point given to :meth:`inverse_kinematics`), ``joint_names``,
    ``payload_link``, take ``(payload, *, params)`` in ``__init__`` and
    implement the underscored, unchecked methods. The public methods validate
    their input and delegate. ``kernel`` is the code of the robot's compiled
    form in :mod:`pdsmc_ros.robots.compiled` (None: numpy only).
    """

    name: ClassVar[str] = ""
    n: ClassVar[int] = 0
    task_dim: ClassVar[int] = 0
    joint_names: ClassVar[tuple[str, ...]] = ()
    passive_joint_names: ClassVar[tuple[str, ...]] = ()
    payload_link: ClassVar[int] = -1
    """Index (from 0) of the link that carries the end-effector (a ``link_com`` payload's link)."""
    kernel: ClassVar[int | None] = None
    params: RobotParams
    payload: float
    J: FloatArray
    B: FloatArray
    effort_limits: FloatArray
    """Largest torque (N m) of each actuated joint, robot order; ``inf`` where unknown."""
    velocity_limits: FloatArray
    """Largest rate (rad/s) of each actuated joint; ``inf`` where unknown."""
    position_limits: FloatArray
    """``(n, 2)`` lower and upper angle (rad) of each actuated joint; ``-inf``/``inf`` if unlimited."""

    def __init__(self, payload: float = 0.0, *, params: RobotParams) -> None:
        self.params = params
        self.payload = float(payload)
        self.J = motor_array(params.motor_inertia, self.n)
        self.B = motor_array(params.motor_damping, self.n)
        self.effort_limits, self.velocity_limits, self.position_limits = joint_limits(params, self.n, self.name)

    @classmethod
    def create(cls, payload: float = 0.0, *, params: RobotParams | None = None) -> Manipulator:
        """The robot with ``params`` (by default its entry of ``config/robots.yaml``)."""
        from .registry import robot_params  # the registry imports this module

        return cls(payload, params=params or robot_params(cls.name))

    def with_payload(self, payload: float) -> Manipulator:
        """The same robot carrying ``payload`` kg at the end-effector."""
        return type(self)(payload, params=self.params)

    def pack(self) -> FloatArray:
        """The flat parameter array of the compiled form (robots with a ``kernel`` only)."""
        raise NotImplementedError(f"{self.name} has no compiled form")

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

    def ik_path(self, p: FloatArray) -> tuple[FloatArray, NDArray[np.bool_]]:
        """Joint angles along a path of task points ``p`` ``(k, task_dim)``, continuous
        from one point to the next, and whether each point is reachable."""
        ok = np.asarray(self.reachable(p))
        if not np.all(ok):
            return np.zeros(p.shape[:-1] + (self.n,)), ok
        return np.unwrap(self._ik(p), axis=0), ok

    def ik_near(self, p: FloatArray, guide: FloatArray) -> FloatArray:
        """Joint angles placing the end effector at ``p``, nearest ``guide`` (same shape
        as the answer): the closed-form solution shifted by whole turns."""
        raw = self._ik(p)
        return raw + 2.0 * np.pi * np.round((guide - raw) / (2.0 * np.pi))

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


def joint_limits(params: RobotParams, n: int, name: str) -> tuple[FloatArray, FloatArray, FloatArray]:
    """``(effort, velocity, position)`` limits of ``params`` for ``n`` actuated joints (unknown: infinite).

    Raises
    ------
    InvalidInputError
        If a limit list does not have ``n`` entries, a magnitude is not > 0, or a lower
        position limit is not below its upper one.
    """
    effort = np.full(n, np.inf)
    velocity = np.full(n, np.inf)
    position = np.tile([-np.inf, np.inf], (n, 1))
    for label, given, out in (("effort", params.effort_limit, effort), ("velocity", params.velocity_limit, velocity)):
        if not given:
            continue
        values = np.asarray(given, dtype=float)
        if values.shape != (n,) or np.any(np.isnan(values)) or np.any(values <= 0.0):
            raise InvalidInputError(f"{name}: limits.{label} needs {n} values > 0 (one per actuated joint), "
                                    f"got {list(given)}")
        out[:] = values
    if params.position_limit:
        pairs = np.asarray(params.position_limit, dtype=float)
        if pairs.shape != (n, 2) or np.any(np.isnan(pairs)) or np.any(pairs[:, 0] >= pairs[:, 1]):
            raise InvalidInputError(f"{name}: limits.position needs {n} pairs [lower, upper] with lower < upper "
                                    f"(rad), got {[list(p) for p in params.position_limit]}")
        position[:] = pairs
    return effort, velocity, position


def motor_array(value: float | FloatArray, n: int) -> FloatArray:
    return np.asarray(value, dtype=float)[..., None] * np.ones(n)


