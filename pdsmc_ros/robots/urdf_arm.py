"""A URDF arm's settings: its Pinocchio model, task plane and options, read and checked once.

:func:`urdf_arm` reads a URDF (file or text) with the options beside it into an
:class:`UrdfArm`: what the registry holds for a URDF arm, and what each
:class:`~.urdf_robot.UrdfRobot` instance is built from (:meth:`UrdfArm.create`).
Conventions (issue 16): URDF ``<dynamics damping>`` is the motor damping ``B``;
``armature`` (an option: URDF has no element for it) the motor inertia ``J``;
``<limit effort velocity lower upper>`` the arm's limits, each overridable by the
options; the task rows the arm follows (its ``orientation``) are described in
:mod:`.urdf_robot`.
"""

from __future__ import annotations

import contextlib
import os
import sys
import tempfile
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any
from xml.etree import ElementTree

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import InvalidInputError
from .base import FloatArray, RobotParams
from .options import per_joint, position_pairs
from .task import TaskPlane

if TYPE_CHECKING:
    from .urdf_robot import UrdfRobot

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

    def create(self, payload: float = 0.0, *, params: RobotParams | None = None) -> UrdfRobot:
        """A robot of this arm (its own Pinocchio data). ``payload`` must be 0: a load is a fixed
        link of the URDF; ``params`` is not used (its parameters are its URDF's)."""
        from .urdf_robot import UrdfRobot  # the robot is built from the arm

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
    damping = np.asarray(model.damping, dtype=float).copy()
    model.armature[:] = 0.0  # J is added by the robot, as for the built-in ones (Mbar = M + J)
    data = model.createData()
    ee_id = model.getFrameId(frame)
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
        },
    )
