"""Any serial arm from its URDF, with Pinocchio: the arm read once, and the robots built from it.

:func:`urdf_arm` reads a URDF (file or text) with the options beside it into an
:class:`UrdfArm`: the arm's Pinocchio model, task plane and options, read and checked once; what
the registry holds for a URDF arm. Each :class:`UrdfRobot` is an instance built from it
(:meth:`UrdfArm.create`), with the interface of the built-in robots (``name``, ``n``,
``joint_names``, ``mass_matrix``, ``coriolis_matrix``, ``gravity``, ``forward_dynamics``, forward
and inverse kinematics, Jacobian), so a registered URDF arm runs wherever ``serial_3r`` does;
:func:`from_urdf` returns one. Conventions (issue 16): URDF ``<dynamics damping>`` is the motor
damping ``B`` (Pinocchio reads it, its ``aba`` does not apply it, so Eq. (4.1) adds it here);
``armature`` (an option: URDF has no element for it) is the motor inertia ``J``, added to the mass
matrix's diagonal; ``<limit effort velocity lower upper>`` the arm's limits, each overridable by the
options; gravity is URDF's, along -z.

Task space: the thesis's planar contours run in a :class:`~.task.TaskPlane`. A task
point is ``(u, v, pose)``: the end effector's plane coordinates and its rotation about
the plane's normal. Which of the six task rows (three positions, three rotations, in
the plane's axes) the arm is asked to follow is its ``orientation``:

``contour``
    a planar arm moving in the plane (its out-of-plane rows are zero): position and
    the contour's pose, as the thesis's serial arm;
``held``
    six or more joints: position, and the orientation of the home configuration held
    (the contour's pose is not used);
``free``
    fewer joints: position only.

Inverse kinematics is numerical: damped least squares, seeded continuously along the
path (:meth:`UrdfRobot.ik_path`) and converged to :data:`IK_TOLERANCE`.
"""

from __future__ import annotations

import contextlib
import json
import os
import sys
import tempfile
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any
from xml.etree import ElementTree
from xml.sax.saxutils import escape

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import InvalidInputError, UnreachableError
from . import ik_kernels, spatial_layout
from .base import GRAVITY, FloatArray, Manipulator, RobotParams
from .options import per_joint, position_pairs
from .task import TaskPlane, axis_rotation, rotation_log

__all__ = ["ORIENTATIONS", "UrdfArm", "UrdfRobot", "from_urdf", "load_model", "task_solve", "urdf_arm"]

ORIENTATIONS = ("contour", "held", "free")


def pinocchio_module() -> Any:
    """The ``pinocchio`` module (a clear line when it is missing)."""
    try:
        import pinocchio
    except ImportError as exc:  # pragma: no cover - a runtime dependency since issue 16
        raise InvalidInputError("URDF robots need Pinocchio (pip package 'pin'): run make setup") from exc
    return pinocchio


@contextlib.contextmanager
def captured_stderr() -> Iterator[Callable[[], list[str]]]:
    """Collect what C++ code (urdfdom's console bridge) writes to file descriptor 2, so a bad
    URDF is our one line instead of the parser's several."""
    sys.stderr.flush()
    saved = os.dup(2)
    with tempfile.TemporaryFile(mode="w+b") as sink:
        os.dup2(sink.fileno(), 2)
        lines: list[str] = []
        try:
            yield lambda: lines
        finally:
            os.dup2(saved, 2)
            os.close(saved)
            sink.seek(0)
            lines.extend(sink.read().decode(errors="replace").splitlines())


def load_model(source: str | Path, *, locked_joints: Sequence[str] = ()) -> tuple[Any, str, str]:
    """``(model, label, urdf_text)`` of a URDF file or text, with ``locked_joints`` fixed at 0
    (a gripper's fingers, say).

    Raises
    ------
    InvalidInputError
        One line naming the file and the problem: no such file, it does not parse, no movable
        joint, a closed chain or a tree, a joint other than revolute or prismatic, an unknown
        locked joint, a moving link without mass.
    """
    pin = pinocchio_module()
    text = str(source)
    is_xml = text.lstrip().startswith("<")
    label = "URDF text" if is_xml else f"URDF {text!r}"
    if not is_xml:
        path = Path(text)
        if not path.is_file():
            raise InvalidInputError(f"{label}: no such file")
        try:
            xml = path.read_text()
        except (OSError, UnicodeDecodeError) as exc:
            raise InvalidInputError(f"{label}: cannot read it ({exc})") from None
    else:
        xml = text
    try:
        ElementTree.fromstring(xml)
    except ElementTree.ParseError as exc:
        raise InvalidInputError(f"{label} does not parse: {exc}") from None
    with captured_stderr() as messages:
        try:
            model = pin.buildModelFromXML(xml)
        except (ValueError, RuntimeError) as exc:
            model, error = None, str(exc).strip()
    if model is None:
        said = [line.strip() for line in messages() if line.strip()]
        reason = said[0] if said else (error.splitlines()[0] if error else "not a URDF model")
        raise InvalidInputError(f"{label} does not parse: {reason}")
    if locked_joints:
        unknown = [j for j in locked_joints if not model.existJointName(j)]
        if unknown:
            raise InvalidInputError(f"{label}: no joint {unknown[0]!r} to lock")
        ids = [model.getJointId(j) for j in locked_joints]
        model = pin.buildReducedModel(model, ids, pin.neutral(model))
    if model.nv == 0:
        raise InvalidInputError(f"{label}: no movable joint")
    for i in range(1, model.njoints):
        kind = model.joints[i].shortname()
        if "UB" in kind:  # Pinocchio's unbounded revolute: (cos, sin) coordinates, nq = 2 nv
            raise InvalidInputError(f"{label}: joint {model.names[i]!r} is continuous; only revolute and "
                                    "prismatic joints are supported (make it type=\"revolute\" with <limit lower= "
                                    "upper=>, or lock it with locked_joints)")
        if not kind.startswith(("JointModelR", "JointModelP")):
            raise InvalidInputError(f"{label}: joint {model.names[i]!r} is neither revolute nor prismatic "
                                    f"({kind.removeprefix('JointModel')}); only those are supported")
    branching = [model.names[i] for i in range(2, model.njoints) if model.parents[i] != i - 1]
    if branching:
        raise InvalidInputError(f"{label}: not a serial chain: joint {branching[0]!r} branches off "
                                f"(lock the joints of other branches, e.g. a gripper's fingers)")
    massless = [model.names[i] for i in range(1, model.njoints) if model.inertias[i].mass <= 0.0]
    if massless:
        raise InvalidInputError(f"{label}: the links moved by {massless} have no mass (an <inertial> is needed)")
    return model, label, xml


@dataclass(frozen=True, eq=False)
class UrdfArm:
    """A URDF arm and its settings (made by :func:`urdf_arm`): what the registry holds for it.

    Attributes
    ----------
    name : str
        The name it is registered and asked by.
    n, joint_names
        Its movable joints.
    model : pinocchio.Model
        Its Pinocchio model (armature zeroed: ``J`` is added by the robot).
    urdf, source : str
        The URDF text, and its file ('' when given as text).
    ee_frame : str
        The end-effector frame.
    armature, damping : ndarray
        ``J`` and ``B`` per joint.
    effort_limits, velocity_limits, position_limits : ndarray
        Its limits (:class:`~.base.Manipulator`).
    home : ndarray
        The configuration inverse kinematics starts from.
    plane : TaskPlane
        Where the contours run.
    orientation : str
        Which task rows it follows (:mod:`.urdf_robot`); ``rows`` their indices.
    reference_rotation : ndarray
        The end effector's rotation at pose 0.
    settings : mapping
        Run settings and presets (``control_rate``, ``contour_size``, ``contours``, ``gains`` ...).
    options : mapping
        The task options it was made with, as plain data (its ``<pdsmc_ros>`` element).
    friction_coulomb : ndarray
        Coulomb friction per joint (N m): carried for the stand-in and the identification, not
        in the laws' model (``damping`` holds the viscous part).
    payload_mass, payload_com
        The options' point mass (kg) and where it is in the end-effector frame (m): already in
        ``model`` (on the inertia of the end-effector frame's joint).
    """

    name: str
    n: int
    joint_names: tuple[str, ...]
    model: Any
    urdf: str
    source: str
    ee_frame: str
    armature: FloatArray
    damping: FloatArray
    effort_limits: FloatArray
    velocity_limits: FloatArray
    position_limits: FloatArray
    home: FloatArray
    plane: TaskPlane
    orientation: str
    reference_rotation: FloatArray
    rows: NDArray[np.intp]
    settings: Mapping[str, Any]
    options: Mapping[str, Any]
    friction_coulomb: FloatArray = field(default_factory=lambda: np.zeros(0))
    payload_mass: float = 0.0
    payload_com: FloatArray = field(default_factory=lambda: np.zeros(3))

    def create(self, payload: float = 0.0, *, params: RobotParams | None = None) -> UrdfRobot:
        """A robot of this arm (its own Pinocchio data). ``payload`` must be 0: a load is a fixed
        link of the URDF; ``params`` is not used (its parameters are its URDF's)."""
        return UrdfRobot(self, payload, params=params)


def _structural_rows(model: Any, data: Any, ee_id: int, basis6: FloatArray) -> NDArray[np.bool_]:
    """Task rows the arm cannot move in any configuration (a planar arm's out-of-plane rows)."""
    pin = pinocchio_module()
    rng = np.random.default_rng(0)
    lo = np.where(np.isfinite(model.lowerPositionLimit), model.lowerPositionLimit, -np.pi)
    hi = np.where(np.isfinite(model.upperPositionLimit), model.upperPositionLimit, np.pi)
    lo, hi = np.maximum(lo, -np.pi), np.minimum(hi, np.pi)
    largest = np.zeros(6)
    for _ in range(8):
        q = rng.uniform(lo, hi)
        pin.computeJointJacobians(model, data, q)
        pin.updateFramePlacement(model, data, ee_id)
        # eigenpy hands a one-joint arm's 6 x 1 Jacobian over as a vector
        jac = basis6 @ np.reshape(pin.getFrameJacobian(model, data, ee_id, pin.LOCAL_WORLD_ALIGNED), (6, -1))
        largest = np.maximum(largest, np.max(np.abs(jac), axis=1))
    return largest < 1e-10


def urdf_arm(
    source: str | Path,
    *,
    name: str | None = None,
    armature: ArrayLike | None = None,
    ee_frame: str | None = None,
    locked_joints: Sequence[str] = (),
    home: ArrayLike | None = None,
    plane: TaskPlane | None = None,
    orientation: str | None = None,
    settings: Mapping[str, Any] | None = None,
    effort_limits: ArrayLike | None = None,
    velocity_limits: ArrayLike | None = None,
    position_limits: ArrayLike | None = None,
    friction_coulomb: ArrayLike | None = None,
    friction_viscous: ArrayLike | None = None,
    payload_mass: float | None = None,
    payload_com: ArrayLike | None = None,
    options_label: str | None = None,
) -> UrdfArm:
    """The arm of a URDF file or text, with its settings (:meth:`UrdfArm.create` builds the robot).

    Parameters
    ----------
    source : str or Path
        The URDF file, or its XML text (``/robot_description``).
    name : str, optional
        The robot's name; by default the URDF's.
    armature : array_like, optional
        Motor inertia ``J`` per movable joint (kg m^2), or one value for all; 0 by default.
    ee_frame : str, optional
        The end-effector frame; by default the URDF's last frame.
    locked_joints : sequence of str
        Joints held at 0 (a gripper's fingers): not part of the arm.
    home : array_like, optional
        The configuration a run's inverse kinematics starts from; all zeros by default.
    plane : TaskPlane, optional
        Where the contours run; by default the vertical plane through the end effector at
        ``home``, facing the base (:meth:`TaskPlane.facing_base`).
    orientation : str, optional
        ``contour``, ``held`` or ``free`` (module docstring); chosen from the arm by default.
    settings : mapping, optional
        Run settings and presets (``control_rate``, ``sample_rate``, ``contour_bound``,
        ``contour_size``, ``contours``, ``gains``), as a robot's entry of a catalog.
    effort_limits, velocity_limits : array_like, optional
        Per joint (or one for all), N m and rad/s, > 0 (``.inf``: unlimited); by default the
        URDF's ``<limit effort velocity>``.
    position_limits : array_like, optional
        ``(n, 2)`` lower and upper limits (rad or m); by default the URDF's ``<limit lower upper>``.
    friction_coulomb, friction_viscous : array_like, optional
        Per joint (or one for all), N m and N m s, >= 0; 0 by default. The viscous friction adds
        to the URDF's ``<dynamics damping>`` (the motor damping ``B``).
    payload_mass, payload_com : optional
        A point mass (kg, >= 0) at ``payload_com`` (m, in the end-effector frame; its origin by
        default), added to the model: a tool or load the URDF does not have.
    options_label : str, optional
        What the options' errors name (the options file); by default the URDF.

    Raises
    ------
    InvalidInputError
        One line naming the file and the problem (:func:`load_model`), an unknown
        end-effector frame, a wrong armature, home or limit.
    """
    pin = pinocchio_module()
    model, label, xml = load_model(source, locked_joints=locked_joints)
    frame = ee_frame or model.frames[model.nframes - 1].name
    if not model.existFrame(frame):
        raise InvalidInputError(f"{label}: no frame {frame!r} (frames: {[f.name for f in model.frames][1:]})")
    n = model.nv
    where = options_label or label
    names = tuple(model.names[i] for i in range(1, model.njoints))
    j = per_joint(0.0 if armature is None else armature, names, "armature", where, lowest=0.0, finite=True)
    q_home = np.zeros(n) if home is None else per_joint(home, names, "home", where, finite=True, single=False)
    effort = per_joint(model.effortLimit if effort_limits is None else effort_limits, names, "effort_limits",
                       where, above=0.0)
    velocity = per_joint(model.velocityLimit if velocity_limits is None else velocity_limits, names,
                         "velocity_limits", where, above=0.0)
    if position_limits is None:
        position = np.stack([np.asarray(model.lowerPositionLimit, dtype=float),
                             np.asarray(model.upperPositionLimit, dtype=float)], axis=-1)
    else:
        position = position_pairs(position_limits, names, where)
    coulomb = per_joint(0.0 if friction_coulomb is None else friction_coulomb, names, "friction_coulomb", where,
                        lowest=0.0, finite=True)
    viscous = per_joint(0.0 if friction_viscous is None else friction_viscous, names, "friction_viscous", where,
                        lowest=0.0, finite=True)
    damping = np.asarray(model.damping, dtype=float).copy() + viscous
    model.armature[:] = 0.0  # J is added by the robot, as for the built-in ones (Mbar = M + J)
    ee_id = model.getFrameId(frame)
    load = 0.0 if payload_mass is None else float(payload_mass)
    load_com = np.zeros(3) if payload_com is None else np.asarray(payload_com, dtype=float)
    if not (np.isfinite(load) and load >= 0.0) or load_com.shape != (3,) or not np.all(np.isfinite(load_com)):
        raise InvalidInputError(f"{where}: payload_mass must be >= 0 kg and payload_com 3 finite numbers (m), got "
                                f"{payload_mass!r} and {payload_com!r}")
    if load > 0.0:  # a point mass at payload_com in the end-effector frame, on that frame's joint
        placed_frame = model.frames[ee_id]
        point = pin.Inertia(load, load_com, np.zeros((3, 3)))
        joint = placed_frame.parentJoint
        model.inertias[joint] = model.inertias[joint] + placed_frame.placement.act(point)
    data = model.createData()
    pin.framesForwardKinematics(model, data, q_home)
    x_home = data.oMf[ee_id].translation.copy()
    r_home = data.oMf[ee_id].rotation.copy()
    placed = plane or TaskPlane.facing_base(x_home)
    basis6 = np.zeros((6, 6))
    basis6[:3, :3] = basis6[3:, 3:] = placed.basis
    fixed = _structural_rows(model, data, ee_id, basis6)
    planar = bool(fixed[2] and fixed[3] and fixed[4])
    mode = orientation or ("contour" if planar else "held" if n >= 6 else "free")
    if mode not in ORIENTATIONS:
        raise InvalidInputError(f"orientation must be one of {', '.join(ORIENTATIONS)}, got {mode!r}")
    wanted = {"contour": range(6), "held": range(6), "free": range(3)}[mode]
    rows = np.array([r for r in wanted if not fixed[r]], dtype=np.intp)
    if mode == "contour":
        pin.framesForwardKinematics(model, data, np.zeros(n))
        reference = data.oMf[ee_id].rotation.copy()  # pose 0: the zero configuration's orientation
    else:
        reference = r_home
    source_file = str(source) if not str(source).lstrip().startswith("<") else ""
    return UrdfArm(
        name=name or model.name, n=n, joint_names=names, model=model, urdf=xml, source=source_file,
        ee_frame=frame, armature=j, damping=damping, effort_limits=effort, velocity_limits=velocity,
        position_limits=position, home=q_home, plane=placed, orientation=mode, reference_rotation=reference,
        rows=rows, settings=dict(settings or {}),
        options={
            "armature": j.tolist(), "ee_frame": frame, "locked_joints": list(locked_joints),
            "home": q_home.tolist(), "plane": placed.describe(), "orientation": mode,
            **({} if effort_limits is None else {"effort_limits": effort.tolist()}),
            **({} if velocity_limits is None else {"velocity_limits": velocity.tolist()}),
            **({} if position_limits is None else {"position_limits": position.tolist()}),
            **({} if friction_coulomb is None else {"friction_coulomb": coulomb.tolist()}),
            **({} if friction_viscous is None else {"friction_viscous": viscous.tolist()}),
            **({} if payload_mass is None else {"payload_mass": load}),
            **({} if payload_com is None else {"payload_com": load_com.tolist()}),
        },
        friction_coulomb=coulomb, payload_mass=load, payload_com=load_com,
    )


IK_TOLERANCE = 1e-14
"""Task error (m and rad, largest row) at which inverse kinematics stops."""
IK_MAX_ITERATIONS = 60
IK_DAMPING = 1e-3
"""Damping of the least-squares step while the error exceeds :data:`IK_UNDAMPED_BELOW`."""
IK_UNDAMPED_BELOW = 1e-5
IK_MAX_STEP = 0.3
"""Largest joint change (rad or m) of one iteration: a step away from a singularity stays local."""
APPROACH_STEPS = 50
"""Intermediate targets from the home configuration to a path's first point."""


class UrdfRobot(Manipulator):
    """A serial arm backed by a Pinocchio model: an instance of an :class:`UrdfArm`
    (its model and settings, shared) with its own Pinocchio data.

    ``payload`` must be 0: a load is a fixed link of the URDF.
    """

    task_dim = 3
    kernel = spatial_layout.SERIAL_CHAIN
    has_link_params = False

    def __init__(self, arm: UrdfArm, payload: float = 0.0, *, params: RobotParams | None = None) -> None:  # noqa: ARG002
        if payload:
            raise InvalidInputError(f"robot {arm.name!r}: a payload on a URDF arm is a fixed link of its URDF "
                                    f"(got payload {payload!r} kg)")
        self.arm = arm
        self.name = arm.name
        self.n = arm.n
        self.joint_names = arm.joint_names
        self.model: Any = arm.model
        self.urdf: str = arm.urdf
        self.source: str = arm.source
        self.ee_frame: str = arm.ee_frame
        self.armature: FloatArray = arm.armature
        self.damping: FloatArray = arm.damping
        self.effort_limits = arm.effort_limits
        self.velocity_limits = arm.velocity_limits
        self.position_limits = arm.position_limits
        self.torque_limit: FloatArray = arm.effort_limits
        """The same array as ``effort_limits`` (its name before the limits were on every robot)."""
        self.velocity_limit: FloatArray = arm.velocity_limits
        self.lower_limit: FloatArray = arm.position_limits[:, 0].copy()
        self.upper_limit: FloatArray = arm.position_limits[:, 1].copy()
        self.home: FloatArray = arm.home
        self.plane: TaskPlane = arm.plane
        self.orientation: str = arm.orientation
        self.reference_rotation: FloatArray = arm.reference_rotation
        self.rows: NDArray[np.intp] = arm.rows
        self.settings: Mapping[str, Any] = arm.settings
        self.options: Mapping[str, Any] = arm.options
        self.payload = 0.0
        self.J = arm.armature.copy()
        self.B = arm.damping.copy()
        self._pin = pinocchio_module()
        self.data = self.model.createData()
        self.ee_id = self.model.getFrameId(self.ee_frame)
        self._basis = self.plane.basis
        self._basis6 = np.zeros((6, 6))
        self._basis6[:3, :3] = self._basis6[3:, 3:] = self._basis
        self._packed: FloatArray | None = None

    def description(self, payload: float | None = None) -> str:  # noqa: ARG002
        """The URDF with this arm's task options and run settings in a ``<pdsmc_ros>`` element
        (URDF parsers ignore unknown elements, as ros2_control's), so a node given
        ``robot:=/robot_description`` rebuilds the very same arm. A load is a link of the URDF:
        ``payload`` is not used."""
        # preset gains are looked up by the arm's name unless its settings name another table
        block = json.dumps({**self.options, "gains": self.name, **self.settings}, sort_keys=True)
        element = f"\n  <pdsmc_ros>{escape(block)}</pdsmc_ros>\n"
        head, closing, tail = self.urdf.rpartition("</robot>")
        return head + element + closing + tail if closing else self.urdf

    def model_source(self) -> tuple[str, float, FloatArray, tuple[str, ...]]:
        return self.urdf, GRAVITY, np.asarray(self.armature, dtype=float), tuple(self.options.get("locked_joints", ()))

    def payload_params(self, payload: float) -> RobotParams:
        raise InvalidInputError(f"robot {self.name!r}: a payload on a URDF arm is a fixed link of its URDF")

    def contour_set(self) -> str:
        """The contour presets its settings name (the serial arm's by default: the thesis's task-space
        contours)."""
        return str(self.settings.get("contours", "serial_3r"))

    def contour_size(self) -> float | None:
        size = self.settings.get("contour_size")
        return float(size) if size else None

    def gains_source(self) -> str | Mapping[str, Any]:
        source = self.settings.get("gains", self.name)
        return source if isinstance(source, Mapping) else str(source)

    def home_configuration(self) -> FloatArray | None:
        return np.asarray(self.home, dtype=float).copy()

    def plane_to_base(self, xy: FloatArray) -> FloatArray:
        return self.plane.world(xy)

    def pack(self) -> FloatArray:
        """Flat parameters of the compiled form (:func:`.spatial_layout.pack`)."""
        return spatial_layout.pack(self.model, self.J, self.B, self.ee_id, self.plane.origin, self.plane.u,
                                    self.plane.v)

    @classmethod
    def create(cls, payload: float = 0.0, *, params: RobotParams | None = None) -> UrdfRobot:
        raise TypeError("a UrdfRobot is built from its arm: UrdfArm.create (or from_urdf)")

    def with_payload(self, payload: float) -> UrdfRobot:
        return UrdfRobot(self.arm, payload)

    # -- per configuration, over any leading batch axes --------------------- #
    def _each(self, fn: Any, *arrays: FloatArray) -> FloatArray:
        batch = arrays[0].shape[:-1]
        flat = [np.reshape(a, (-1, a.shape[-1])) for a in arrays]
        out = [np.asarray(fn(*(a[i] for a in flat))) for i in range(flat[0].shape[0])]
        return np.reshape(np.stack(out), batch + out[0].shape)

    # -- dynamics (Eq. 4.1) --------------------------------------------------- #
    def _mass_matrix(self, q: FloatArray) -> FloatArray:
        def one(qi: FloatArray) -> FloatArray:
            m = self._pin.crba(self.model, self.data, qi)
            m = np.triu(m) + np.triu(m, 1).T  # crba fills the upper triangle
            return m + np.diag(self.J)
        return self._each(one, q)

    def _velocity_product(self, q: FloatArray, qd: FloatArray) -> FloatArray:
        """``C(q, qd) qd`` (Pinocchio's bias without gravity)."""
        pin = self._pin
        return pin.nonLinearEffects(self.model, self.data, q, qd) - pin.computeGeneralizedGravity(
            self.model, self.data, q)

    def _coriolis_matrix(self, q: FloatArray, qd: FloatArray) -> FloatArray:
        """The Christoffel-symbol ``C``: ``C_ij = sum_k Gamma_ijk qd_k``, as the thesis derives it.

        ``c(x) = C(q, x) x`` is a quadratic form with ``Gamma`` symmetric in its last two indices,
        so column ``j`` is ``C(q, qd) e_j = (c(qd + e_j) - c(qd - e_j)) / 4`` (Pinocchio's own
        ``computeCoriolisMatrix`` is another factorisation with the same ``C qd``).
        """
        eye = np.eye(self.n)

        def one(qi: FloatArray, vi: FloatArray) -> FloatArray:
            return np.stack([0.25 * (self._velocity_product(qi, vi + e) - self._velocity_product(qi, vi - e))
                             for e in eye], axis=-1)
        return self._each(one, q, qd)

    def _coriolis_vector(self, q: FloatArray, qd: FloatArray) -> FloatArray:
        return self._each(self._velocity_product, q, qd)

    def _gravity(self, q: FloatArray) -> FloatArray:
        return self._each(lambda qi: self._pin.computeGeneralizedGravity(self.model, self.data, qi).copy(), q)

    def _bias(self, q: FloatArray, qd: FloatArray) -> tuple[FloatArray, FloatArray]:
        nle = self._each(lambda qi, vi: self._pin.nonLinearEffects(self.model, self.data, qi, vi).copy(), q, qd)
        return self._mass_matrix(q), nle

    def _potential(self, q: FloatArray) -> FloatArray:
        return self._each(lambda qi: np.array(self._pin.computePotentialEnergy(self.model, self.data, qi)), q)

    # -- kinematics of the end-effector frame ------------------------------- #
    def ee_pose(self, q: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Position (m) and rotation of the end-effector frame in the base, one configuration."""
        pin = self._pin
        pin.forwardKinematics(self.model, self.data, q)
        placement = pin.updateFramePlacement(self.model, self.data, self.ee_id)
        return placement.translation.copy(), placement.rotation.copy()

    def ee_jacobian(self, q: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Position, rotation and the 6 x n frame Jacobian (base-aligned: linear, angular)."""
        pin = self._pin
        pin.computeJointJacobians(self.model, self.data, q)
        placement = pin.updateFramePlacement(self.model, self.data, self.ee_id)
        jac = pin.getFrameJacobian(self.model, self.data, self.ee_id, pin.LOCAL_WORLD_ALIGNED)
        return placement.translation.copy(), placement.rotation.copy(), jac

    def _fk(self, q: FloatArray) -> FloatArray:
        def one(qi: FloatArray) -> FloatArray:
            x, r = self.ee_pose(qi)
            uv = self.plane.coordinates(x)
            pose = float(self.plane.normal @ rotation_log(r @ self.reference_rotation.T))
            return np.array([uv[0], uv[1], pose])
        return self._each(one, q)

    def position(self, q: FloatArray) -> FloatArray:
        return self._each(lambda qi: self.plane.coordinates(self.ee_pose(qi)[0]), q)

    def _jacobian(self, q: FloatArray) -> FloatArray:
        """Rows ``d(u, v, pose) / dq``."""
        return self._each(lambda qi: (self._basis6 @ self.ee_jacobian(qi)[2])[[0, 1, 5]], q)

    # -- inverse kinematics (compiled: .ik_kernels) --------------------------- #
    def targets(self, p: FloatArray) -> tuple[FloatArray, FloatArray]:
        """World positions ``(k, 3)`` and rotations ``(k, 3, 3)`` of task points ``p = (u, v[, pose])``."""
        p = np.atleast_2d(p)
        x = self.plane.world(p[:, :2])
        if self.orientation == "contour" and p.shape[-1] > 2:
            return x, axis_rotation(self.plane.normal, p[:, 2]) @ self.reference_rotation
        return x, np.broadcast_to(self.reference_rotation, (p.shape[0], 3, 3)).copy()

    def _solve(self, x_d: FloatArray, r_d: FloatArray, seeds: FloatArray, *, chained: bool
               ) -> tuple[FloatArray, NDArray[np.bool_]]:
        count = x_d.shape[0]
        out = np.zeros((count, self.n))
        ok = np.zeros(count, dtype=np.bool_)
        if count:
            if self._packed is None:
                self._packed = self.pack()
            ik_kernels.solve_points(
                self._packed, np.ascontiguousarray(x_d), np.ascontiguousarray(r_d), np.ascontiguousarray(seeds),
                chained, self.rows, np.ascontiguousarray(self._basis), self.lower_limit, self.upper_limit,
                IK_TOLERANCE, IK_MAX_ITERATIONS, IK_DAMPING, IK_UNDAMPED_BELOW, IK_MAX_STEP, out, ok,
                np.empty(ik_kernels.scratch_size(self.n)))
        return out, ok

    def ik_path(self, p: FloatArray) -> tuple[FloatArray, NDArray[np.bool_]]:
        """Along the path: from the home configuration to the first point in
        :data:`APPROACH_STEPS` straight-line steps (rotation about one axis), then each
        point seeded with the solution of the one before."""
        x_d, r_d = self.targets(p)
        x_home, r_home = self.ee_pose(self.home)
        turn = rotation_log(r_d[0] @ r_home.T)
        s = np.linspace(0.0, 1.0, APPROACH_STEPS + 1)[1:-1]
        approach_x = x_home + s[:, None] * (x_d[0] - x_home)
        angle = float(np.linalg.norm(turn))
        approach_r = axis_rotation(turn / angle if angle else turn, s * angle) @ r_home
        seeds = np.broadcast_to(self.home, (1, self.n))
        q, ok = self._solve(np.concatenate([approach_x, x_d]), np.concatenate([approach_r, r_d]), seeds,
                            chained=True)
        return q[len(s):], ok[len(s):]

    def ik_near(self, p: FloatArray, guide: FloatArray) -> FloatArray:
        """Each point solved from its guide (the path's solution interpolated at its time).

        Raises
        ------
        UnreachableError
            If a point does not converge (within the joint limits) from its guide.
        """
        x_d, r_d = self.targets(p.reshape(-1, p.shape[-1]))
        q, ok = self._solve(x_d, r_d, guide.reshape(-1, self.n), chained=False)
        if not np.all(ok):
            bad = int(np.argmin(ok))
            raise UnreachableError(f"{self.name}: inverse kinematics does not reach task point "
                                   f"{np.array2string(p.reshape(-1, p.shape[-1])[bad], precision=6)} from its guide")
        return q.reshape(p.shape[:-1] + (self.n,))

    def reachable(self, p: ArrayLike) -> NDArray[np.bool_]:
        """Whether each point of the path ``p`` is reached, following it from the home configuration."""
        return self.ik_path(np.asarray(p, dtype=float))[1]

    def _ik(self, p: FloatArray) -> FloatArray:
        q, ok = self.ik_path(np.atleast_2d(p))
        if not np.all(ok):
            raise UnreachableError(f"{self.name}: task point {np.array2string(np.atleast_2d(p)[int(np.argmin(ok))])}"
                                   " is out of reach")
        return q.reshape(p.shape[:-1] + (self.n,))

    def task_motion(self, pd: FloatArray) -> FloatArray:
        """The followed rows of the task velocity (or acceleration) of ``pd = (u', v'[, pose'])``."""
        out = np.zeros(6)
        out[0:2] = pd[:2]
        if self.orientation == "contour" and pd.shape[-1] > 2:
            out[5] = pd[2]  # the pose turns about the plane's normal: omega = pose' e_n
        return out[self.rows]

    def joint_rates(self, q: FloatArray, pd: FloatArray, pdd: FloatArray) -> tuple[FloatArray, FloatArray]:
        """``J qd = pd`` and ``J qdd = pdd - Jdot qd`` over the followed rows (minimum norm when the
        arm is redundant); ``Jdot qd`` is the frame's classical acceleration at ``qdd = 0``."""
        pin = self._pin
        qd_out = np.empty_like(q)
        qdd_out = np.empty_like(q)
        flat = (q.reshape(-1, self.n), pd.reshape(-1, pd.shape[-1]), pdd.reshape(-1, pdd.shape[-1]),
                qd_out.reshape(-1, self.n), qdd_out.reshape(-1, self.n))
        for qi, pdi, pddi, qdo, qddo in zip(*flat, strict=True):
            _, _, jac = self.ee_jacobian(qi)
            jac = (self._basis6 @ jac)[self.rows]
            qdo[:] = task_solve(jac, self.task_motion(pdi), 0.0)
            pin.forwardKinematics(self.model, self.data, qi, qdo, np.zeros(self.n))
            acc = pin.getFrameClassicalAcceleration(self.model, self.data, self.ee_id, pin.LOCAL_WORLD_ALIGNED)
            drift = (self._basis6 @ np.concatenate([acc.linear, acc.angular]))[self.rows]
            qddo[:] = task_solve(jac, self.task_motion(pddi) - drift, 0.0)
        return qd_out, qdd_out


def task_solve(jac: FloatArray, b: FloatArray, damping: float) -> FloatArray:
    """``dq`` with ``jac dq = b``: square -> exact; more joints than rows -> the least-norm
    (damped) solution ``J^T (J J^T + damping I)^-1 b``; fewer -> least squares."""
    m, n = jac.shape
    if m == n and damping == 0.0:
        return np.linalg.solve(jac, b)
    if m <= n:
        return jac.T @ np.linalg.solve(jac @ jac.T + damping * np.eye(m), b)
    return np.linalg.solve(jac.T @ jac + damping * np.eye(n), jac.T @ b)


def from_urdf(source: str | Path, *, armature: ArrayLike | None = None, ee_frame: str | None = None,
              name: str | None = None, **options: Any) -> UrdfRobot:
    """A robot from a URDF file (or the URDF text itself); see :func:`urdf_arm`."""
    return urdf_arm(source, armature=armature, ee_frame=ee_frame, name=name, **options).create()
