"""What every robot is: the :class:`Manipulator` interface (numpy only); its parameters are
:mod:`.params`' (re-exported here).

Every function accepts a leading batch dimension: ``q`` of shape ``(..., n)``.
A robot implements the underscored, unchecked methods; the public methods
validate their input and delegate. A robot with a compiled form (numba) also
sets :attr:`Manipulator.kernel` and implements :meth:`Manipulator.pack`; one
without runs behind :mod:`pdsmc_ros.robots.python_form` (its numpy methods called from the
one compiled loop).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any, ClassVar

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import InvalidInputError
from .params import GRAVITY, FloatArray, LinkParams, RobotParams, joint_limits, motor_array

__all__ = ["GRAVITY", "FloatArray", "LinkParams", "Manipulator", "RobotParams", "as_vector", "diag", "joint_limits",
           "motor_array", "suffix_sum"]


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


def diag(values: FloatArray) -> FloatArray:
    """Diagonal matrices from the last axis of ``values``."""
    return values[..., :, None] * np.eye(values.shape[-1])


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

    name: str = ""
    n: int = 0
    task_dim: int = 0
    joint_names: tuple[str, ...] = ()
    passive_joint_names: tuple[str, ...] = ()
    payload_link: int = -1
    """Index (from 0) of the link that carries the end-effector (a ``link_com`` payload's link)."""
    kernel: int | None = None
    has_link_params: ClassVar[bool] = True
    """Whether the robot is built from a :class:`RobotParams` (links and motors) that a run may
    vary (Monte Carlo, payloads); a URDF arm's are its URDF's."""
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
        """The robot with ``params`` (:func:`~pdsmc_ros.robots.make_robot` gives its configured ones)."""
        if params is None:
            raise InvalidInputError(f"robot {cls.name!r} is built from its parameters: make_robot({cls.name!r}) "
                                    "reads them from its configuration")
        return cls(payload, params=params)

    def with_payload(self, payload: float) -> Manipulator:
        """The same robot carrying ``payload`` kg at the end-effector."""
        return type(self)(payload, params=self.params)

    def pack(self) -> FloatArray:
        """The flat parameter array of the compiled form (robots with a ``kernel`` only)."""
        raise NotImplementedError(f"{self.name} has no compiled form")

    # -- what differs between kinds of robot ----------------------------------- #
    def description(self, payload: float | None = None) -> str:
        """The robot's URDF (the plant's ``/robot_description``), with ``payload`` kg at the end
        effector (default: the robot's own payload).

        Raises
        ------
        InvalidInputError
            The robot has no URDF.
        """
        raise InvalidInputError(f"no URDF for robot {self.name!r}")

    def model_source(self) -> tuple[str, float, FloatArray, tuple[str, ...]]:
        """What a physics engine (MuJoCo) builds the robot from: its URDF, gravity along -z
        (m/s^2), the motor inertia of each joint (kg m^2) and the joints locked at 0."""
        return self.description(), self.params.gravity, self.J, ()

    def payload_params(self, payload: float) -> RobotParams:
        """The robot's parameters with ``payload`` kg added to the mass of the link that carries
        the end effector (:attr:`payload_link`), at its centre of mass; its inertia unchanged."""
        links = list(self.params.links)
        k = self.payload_link
        links[k] = dataclasses.replace(links[k], mass=links[k].mass + payload)
        return dataclasses.replace(self.params, links=tuple(links))

    def contour_set(self) -> str:
        """Whose contour presets the robot runs (``config/contours.yaml``): its own."""
        return self.name

    def contour_size(self) -> float | None:
        """The size (m) its contour presets are fitted to; None: as they are."""
        return None

    def gains_source(self) -> str | Mapping[str, Any]:
        """Where its preset gains are: a robot's name in ``config/gains.yaml`` (its own), or the tables."""
        return self.name

    def home_configuration(self) -> FloatArray | None:
        """The configuration a run starts from when it names none; None: the contour's start."""
        return None

    def plane_to_base(self, xy: FloatArray) -> FloatArray:
        """The base-frame point of a task-plane point: the thesis arms' plane is the URDF's x-z."""
        return np.array([xy[0], 0.0, xy[1]])

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
