"""The arm's joint torque, linear in its parameters: what identification estimates.

``tau = Y(q, qd, qdd) pi`` (Gautier & Khalil's inverse dynamic identification model), with
``pi`` the *standard* parameters, in this order (:class:`ParameterLayout`):

* each moving body's ten inertial parameters in Pinocchio's layout
  (``computeJointTorqueRegressor``, ``Inertia.toDynamicParameters``): mass ``m``, first moments
  ``mx, my, mz`` (mass times the centre of mass) and the inertia about the joint frame's origin
  ``Ixx, Ixy, Iyy, Ixz, Iyz, Izz``, in the frame of the body's joint -- the URDF's child link of
  that joint, with every link fixed to it merged in (Pinocchio's body);
* the payload's ten, in the end-effector frame (the tool frame): a body rigidly on the
  end-effector's link, mapped onto that link's columns by :func:`placement_map`;
* each joint's motor inertia ``armature`` (``J qdd``), Coulomb friction ``friction_coulomb``
  (``fc sign(qd)``) and viscous friction ``friction_viscous`` (``fv qd``): the names of the
  arm's options (:mod:`pdsmc_ros.robots.options`) and of the MuJoCo stand-in.

The rigid-body part is Pinocchio's regressor, which this module holds against ``rnea``
(test/identification). Gravity is the URDF's (-z).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from ..errors import InvalidInputError
from ..robots.base import FloatArray
from ..robots.urdf_robot import UrdfArm, pinocchio_module

__all__ = ["INERTIAL_FIELDS", "JOINT_FIELDS", "ArmDynamics", "ParameterLayout", "arm_of", "placement_map",
           "pseudo_inertia"]

INERTIAL_FIELDS = ("m", "mx", "my", "mz", "Ixx", "Ixy", "Iyy", "Ixz", "Iyz", "Izz")
"""A body's ten inertial parameters, in Pinocchio's order."""
JOINT_FIELDS = ("armature", "friction_coulomb", "friction_viscous")
"""The per-joint parameters, in order (the arm's option names)."""
PAYLOAD = "payload"
"""The payload's name among the bodies."""


def _skew(v: FloatArray) -> FloatArray:
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def _unpack(p: FloatArray) -> tuple[float, FloatArray, FloatArray]:
    """``(m, h, I)`` of ten parameters (``h = m c``, ``I`` about the frame's origin)."""
    inertia = np.array([[p[4], p[5], p[7]], [p[5], p[6], p[8]], [p[7], p[8], p[9]]])
    return float(p[0]), np.asarray(p[1:4], dtype=float), inertia


def _pack(m: float, h: FloatArray, inertia: FloatArray) -> FloatArray:
    return np.array([m, *h, inertia[0, 0], inertia[0, 1], inertia[1, 1], inertia[0, 2], inertia[1, 2],
                     inertia[2, 2]])


def placement_map(rotation: ArrayLike, translation: ArrayLike) -> FloatArray:
    """The 10 x 10 matrix taking a body's parameters in a frame ``B`` to those in frame ``A``,
    where ``B`` sits at ``translation`` with ``rotation`` in ``A`` (a rigid placement ``A <- B``).

    Linear in the parameters: ``m' = m``, ``h' = R h + m p``, and the inertia about ``A``'s
    origin ``I' = R I R^T - S(R h) S(p) - S(p) S(R h) - m S(p)^2`` (``S`` the cross-product
    matrix; the parallel-axis theorem for a moved origin), which is what Pinocchio's
    ``SE3.act(Inertia)`` computes.
    """
    rot = np.asarray(rotation, dtype=float)
    p = np.asarray(translation, dtype=float)
    sp = _skew(p)
    out = np.empty((10, 10))
    for k in range(10):
        e = np.zeros(10)
        e[k] = 1.0
        m, h, inertia = _unpack(e)
        rh = rot @ h
        moved = rot @ inertia @ rot.T - _skew(rh) @ sp - sp @ _skew(rh) - m * sp @ sp
        out[:, k] = _pack(m, rh + m * p, moved)
    return out


def pseudo_inertia(p: ArrayLike) -> FloatArray:
    """The 4 x 4 pseudo-inertia ``[[Sigma, h], [h^T, m]]`` of ten parameters, ``Sigma = tr(I)/2 1 - I``
    the second moment of the mass about the frame's origin. Positive definite exactly when the
    parameters are those of a body of positive density (Wensing, Kim & Slotine 2017): positive
    mass, positive definite inertia about the centre of mass and the triangle inequalities."""
    m, h, inertia = _unpack(np.asarray(p, dtype=float))
    sigma = 0.5 * np.trace(inertia) * np.eye(3) - inertia
    out = np.empty((4, 4))
    out[:3, :3] = sigma
    out[:3, 3] = out[3, :3] = h
    out[3, 3] = m
    return out


@dataclass(frozen=True)
class ParameterLayout:
    """Where each standard parameter sits in ``pi``, and its name.

    Attributes
    ----------
    joint_names : tuple of str
        The arm's joints, in its order.
    bodies : tuple of str
        The URDF link each joint moves (its child link), one per joint.
    """

    joint_names: tuple[str, ...]
    bodies: tuple[str, ...]

    @property
    def n(self) -> int:
        return len(self.joint_names)

    @property
    def size(self) -> int:
        return 10 * self.n + 10 + len(JOINT_FIELDS) * self.n

    @property
    def links(self) -> slice:
        return slice(0, 10 * self.n)

    def link(self, i: int) -> slice:
        return slice(10 * i, 10 * i + 10)

    @property
    def payload(self) -> slice:
        return slice(10 * self.n, 10 * self.n + 10)

    def joint_field(self, name: str) -> slice:
        start = 10 * self.n + 10 + JOINT_FIELDS.index(name) * self.n
        return slice(start, start + self.n)

    @property
    def names(self) -> tuple[str, ...]:
        """``link.field`` for the bodies (``payload.m`` ...), ``field.joint`` for the joints."""
        out = [f"{body}.{f}" for body in self.bodies for f in INERTIAL_FIELDS]
        out += [f"{PAYLOAD}.{f}" for f in INERTIAL_FIELDS]
        out += [f"{field}.{joint}" for field in JOINT_FIELDS for joint in self.joint_names]
        return tuple(out)


class ArmDynamics:
    """An arm's identification model: its layout, its regressor and its own (prior) parameters.

    Parameters
    ----------
    arm : UrdfArm
        The arm (:func:`~pdsmc_ros.robots.urdf_robot.urdf_arm`): its URDF's links, its options'
        armature, friction and payload are the prior :attr:`nominal`.

    Attributes
    ----------
    layout : ParameterLayout
    model : pinocchio.Model
        The arm's links without the options' payload (the payload is a parameter of its own).
    nominal : ndarray
        The arm's own standard parameters (what the URDF and its options say).
    payload_joint : int
        The joint whose body carries the end-effector frame (0-based).
    payload_to_body : ndarray, shape (10, 10)
        :func:`placement_map` of the end-effector frame in that body.
    """

    def __init__(self, arm: UrdfArm) -> None:
        pin = pinocchio_module()
        self.arm = arm
        self._pin = pin
        model = arm.model.copy()
        n = arm.n
        frame = model.frames[model.getFrameId(arm.ee_frame)]
        self.payload_joint = int(frame.parentJoint) - 1
        if self.payload_joint < 0:
            raise InvalidInputError(f"robot {arm.name!r}: its end-effector frame {arm.ee_frame!r} does not move")
        placement = frame.placement
        self.payload_to_body = placement_map(placement.rotation, placement.translation)
        payload = np.zeros(10)
        if arm.payload_mass > 0.0:
            payload = pin.Inertia(arm.payload_mass, np.asarray(arm.payload_com, dtype=float),
                                  np.zeros((3, 3))).toDynamicParameters()
            body = frame.parentJoint
            bare = model.inertias[body].toDynamicParameters() - self.payload_to_body @ payload
            model.inertias[body] = pin.Inertia.FromDynamicParameters(bare)
        self.model = model
        self.data = model.createData()
        self.layout = ParameterLayout(arm.joint_names, _moved_links(arm))
        nominal = np.zeros(self.layout.size)
        for i in range(n):
            nominal[self.layout.link(i)] = _a_body(pin, model.inertias[i + 1]).toDynamicParameters()
        nominal[self.layout.payload] = payload
        nominal[self.layout.joint_field("armature")] = arm.armature
        nominal[self.layout.joint_field("friction_coulomb")] = (
            arm.friction_coulomb if arm.friction_coulomb.size == n else np.zeros(n))
        nominal[self.layout.joint_field("friction_viscous")] = arm.damping
        self.nominal = nominal

    @property
    def n(self) -> int:
        return self.arm.n

    def regressor(self, q: ArrayLike, qd: ArrayLike, qdd: ArrayLike) -> FloatArray:
        """``Y`` of samples ``(k, n)``: shape ``(k * n, p)``, row ``s * n + j`` joint ``j``'s torque at
        sample ``s``."""
        q, qd, qdd = (np.atleast_2d(np.asarray(x, dtype=float)) for x in (q, qd, qdd))
        k, n = q.shape
        layout = self.layout
        out = np.zeros((k, n, layout.size))
        rigid = out[:, :, layout.links]
        for s in range(k):
            rigid[s] = self._pin.computeJointTorqueRegressor(self.model, self.data, q[s], qd[s], qdd[s])
        body = layout.link(self.payload_joint)
        out[:, :, layout.payload] = out[:, :, body] @ self.payload_to_body
        rows = np.arange(n)
        for field, signal in zip(JOINT_FIELDS, (qdd, np.sign(qd), qd), strict=True):
            out[:, rows, layout.joint_field(field).start + rows] = signal
        return out.reshape(k * n, layout.size)

    def torque(self, parameters: ArrayLike, q: ArrayLike, qd: ArrayLike, qdd: ArrayLike) -> FloatArray:
        """Joint torques ``(k, n)`` of ``parameters`` at the samples (any parameters: the regressor)."""
        q = np.atleast_2d(np.asarray(q, dtype=float))
        out: FloatArray = (self.regressor(q, qd, qdd) @ np.asarray(parameters, dtype=float)).reshape(q.shape)
        return out

    def body_model(self, parameters: ArrayLike) -> Any:
        """A Pinocchio model of this arm whose bodies carry ``parameters``' links, the payload on its
        link (each body's sum must be a body: physically consistent parameters)."""
        p = np.asarray(parameters, dtype=float)
        model = self.model.copy()
        for i in range(self.n):
            ten = p[self.layout.link(i)].copy()
            if i == self.payload_joint:
                ten += self.payload_to_body @ p[self.layout.payload]
            model.inertias[i + 1] = self._pin.Inertia.FromDynamicParameters(ten)
        return model

    def consistent_torque(self, parameters: ArrayLike, q: ArrayLike, qd: ArrayLike, qdd: ArrayLike) -> FloatArray:
        """:meth:`torque` of physically consistent ``parameters`` by Pinocchio's ``rnea`` (many
        samples: about ten times faster than the regressor)."""
        p = np.asarray(parameters, dtype=float)
        q, qd, qdd = (np.atleast_2d(np.asarray(x, dtype=float)) for x in (q, qd, qdd))
        model = self.body_model(p)
        data = model.createData()
        rnea = self._pin.rnea
        out = np.array([rnea(model, data, q[s], qd[s], qdd[s]) for s in range(len(q))]).reshape(q.shape)
        layout = self.layout
        out += p[layout.joint_field("armature")] * qdd + p[layout.joint_field("friction_coulomb")] * np.sign(qd)
        out += p[layout.joint_field("friction_viscous")] * qd
        return out


def _a_body(pin: Any, inertia: Any) -> Any:
    """A link's URDF inertial as a body's: unchanged if its principal moments obey the triangle
    inequality; else the middle one raised to the largest -- a thin rod along the smallest's axis,
    strictly a body if the smallest is positive; the MuJoCo stand-in makes the thesis arms' planar
    placeholder (``ixx = izz = 1e-6``, ``iyy`` the link's) a rod alike, ``izz = iyy + ixx``
    (:func:`pdsmc_ros.sim.mujoco_model.mujoco_urdf`): the same to 1e-6 kg m^2, about axes the
    planar arm's torques do not see.

    Why: the URDF's links are the consistent fit's prior (:mod:`.consistent`), what it keeps where the
    torques do not decide. A prior that is no body cannot be kept: the fit must move the links, and
    the payload -- which a planar arm's torques see only in sums with the last link's mass and the
    one before's first moment -- takes up whatever that move leaves (on the serial 3R with exact base
    parameters: 0.266 kg for 0.2, docs/how-to/identify.md)."""
    rotational = np.asarray(inertia.inertia, dtype=float)
    moments, axes = np.linalg.eigh(rotational)  # ascending
    if moments[2] <= moments[0] + moments[1]:
        return inertia
    moments = np.array([moments[0], moments[2], moments[2]])
    body = axes @ np.diag(moments) @ axes.T
    return pin.Inertia(float(inertia.mass), np.asarray(inertia.lever, dtype=float).copy(), 0.5 * (body + body.T))


def _moved_links(arm: UrdfArm) -> tuple[str, ...]:
    """The URDF child link of each of the arm's joints (the link whose frame is the joint's)."""
    from xml.etree import ElementTree

    root = ElementTree.fromstring(arm.urdf)
    child = {j.get("name"): j.find("child") for j in root.findall("joint")}
    out = []
    for name in arm.joint_names:
        element: Any = child.get(name)
        out.append(element.get("link") if element is not None else name)
    return tuple(out)


THESIS_TWINS = {"serial_3r": "serial_3r.urdf"}
"""Built-in arms with a URDF twin in ``config/urdf`` (the same model through Pinocchio)."""


def arm_of(robot: str) -> UrdfArm:
    """The URDF arm ``robot`` names (``--robot``): an arm of example-robot-data, a ``.urdf`` path,
    or a built-in arm's URDF twin (``serial_3r``: ``config/urdf/serial_3r.urdf``).

    Raises
    ------
    InvalidInputError
        An unknown robot, or one identification cannot model (the five-bar: a closed chain).
    """
    from ..resources import config_dir
    from ..robots.catalog import resolve_robot
    from ..robots.registry import make_robot
    from ..robots.urdf_robot import UrdfRobot

    key = resolve_robot(robot)
    if key in THESIS_TWINS:
        key = resolve_robot(str(config_dir() / "urdf" / THESIS_TWINS[key]))
    built = make_robot(key)
    if not isinstance(built, UrdfRobot):
        raise InvalidInputError(f"robot {robot!r}: identification needs a serial arm with a URDF (an arm of "
                                f"example-robot-data, a .urdf file, or serial_3r); {robot} is a closed chain")
    return built.arm
