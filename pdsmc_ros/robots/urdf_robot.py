"""Any serial arm from its URDF, with Pinocchio (numpy path; issue 16's first part).

:func:`from_urdf` returns a :class:`UrdfRobot` with the interface of the built-in robots:
``joint_names``, ``mass_matrix``, ``coriolis_matrix``, ``gravity``, ``forward_dynamics``,
forward kinematics of the end-effector frame (its position, metres) and its Jacobian. Conventions
(the issue's): URDF ``<dynamics damping>`` is the motor damping ``B`` (Pinocchio reads it but its
``aba`` does not apply it, so Eq. (4.1) adds it here); ``armature`` is the motor inertia ``J`` (URDF
has no element for it), added to the mass matrix's diagonal; ``<limit effort velocity>`` are
:attr:`UrdfRobot.torque_limit` and :attr:`UrdfRobot.velocity_limit`; gravity is URDF's, along -z.

Not yet: inverse kinematics (task-space contours on such an arm), robots by name from
example-robot-data, a compiled form.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, ClassVar

import numpy as np
from numpy.typing import ArrayLike

from ..errors import InvalidInputError
from .base import FloatArray, Manipulator


def _pinocchio() -> Any:
    try:
        import pinocchio
    except ImportError as exc:  # pragma: no cover - a runtime dependency since issue 16
        raise InvalidInputError("URDF robots need Pinocchio (pip package 'pin'): run make setup") from exc
    return pinocchio


def from_urdf(source: str | Path, *, armature: ArrayLike | None = None, ee_frame: str | None = None,
              name: str | None = None) -> UrdfRobot:
    """A robot from a URDF file (or the URDF text itself).

    Parameters
    ----------
    source : str or Path
        The URDF file, or its XML text (``/robot_description``).
    armature : array_like, optional
        Motor inertia ``J`` per movable joint (kg m^2), or one value for all; 0 by default.
    ee_frame : str, optional
        The end-effector frame; by default the URDF's last frame.
    name : str, optional
        The robot's name; by default the URDF's.

    Raises
    ------
    InvalidInputError
        One line naming the file and the problem: it does not parse, has no movable joint, a
        joint other than revolute or prismatic, an unknown end-effector frame, a moving link
        without mass.
    """
    pin = _pinocchio()
    text = str(source)
    is_xml = text.lstrip().startswith("<")
    label = "URDF text" if is_xml else f"URDF {text!r}"
    try:
        if not is_xml and not Path(text).is_file():
            raise InvalidInputError(f"{label}: no such file")
        model = pin.buildModelFromXML(text) if is_xml else pin.buildModelFromUrdf(text)
    except InvalidInputError:
        raise
    except (ValueError, RuntimeError) as exc:
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise InvalidInputError(f"{label} does not parse: {first}") from None
    if model.nv == 0:
        raise InvalidInputError(f"{label}: no movable joint")
    kinds = {model.joints[i].shortname() for i in range(1, model.njoints)}
    unsupported = sorted(k for k in kinds if not k.startswith(("JointModelR", "JointModelP")))
    if unsupported or model.nq != model.nv:
        raise InvalidInputError(f"{label}: only revolute and prismatic joints are supported, found {unsupported}")
    masses = [model.inertias[i].mass for i in range(1, model.njoints)]
    massless = [model.names[i] for i, m in enumerate(masses, 1) if m <= 0.0]
    if massless:
        raise InvalidInputError(f"{label}: the links moved by {massless} have no mass (an <inertial> is needed)")
    frame = ee_frame or model.frames[model.nframes - 1].name
    if not model.existFrame(frame):
        raise InvalidInputError(f"{label}: no frame {frame!r} (frames: {[f.name for f in model.frames][1:]})")
    n = model.nv
    j = np.broadcast_to(np.asarray(0.0 if armature is None else armature, dtype=float), (n,)).copy()
    if not np.all(np.isfinite(j)) or np.any(j < 0.0):
        raise InvalidInputError(f"armature must be {n} finite values >= 0, got {j.tolist()}")
    return UrdfRobot(model, frame, j, name=name or model.name)


class UrdfRobot(Manipulator):
    """A serial arm backed by a Pinocchio model (see :func:`from_urdf`).

    The task point is the end-effector frame's position (metres, base frame).
    """

    task_dim: ClassVar[int] = 3
    kernel: ClassVar[int | None] = None

    def __init__(self, model: Any, ee_frame: str, armature: FloatArray, *, name: str = "urdf") -> None:
        pin = _pinocchio()
        self.model = model
        self.data = model.createData()
        self.ee_frame = ee_frame
        self.ee_id = model.getFrameId(ee_frame)
        n = model.nv
        self.n_joints = n
        self.robot_name = name
        self.joint_names_ = tuple(model.names[i] for i in range(1, model.njoints))
        self.payload = 0.0
        self.J = np.asarray(armature, dtype=float)
        self.B = np.asarray(model.damping, dtype=float).copy()
        self.torque_limit = np.asarray(model.effortLimit, dtype=float).copy()
        self.velocity_limit = np.asarray(model.velocityLimit, dtype=float).copy()
        self._pin = pin
        model.armature[:] = 0.0  # J is added here, as for the built-in robots (Mbar = M + J)

    @property
    def n(self) -> int:  # type: ignore[override]
        return self.n_joints

    @property
    def name(self) -> str:  # type: ignore[override]
        return self.robot_name

    @property
    def joint_names(self) -> tuple[str, ...]:  # type: ignore[override]
        return self.joint_names_

    def with_payload(self, payload: float) -> UrdfRobot:
        raise InvalidInputError("a payload on a URDF robot: add it to the URDF as a fixed link")

    # -- per configuration, over any leading batch axes --------------------- #
    def _each(self, fn: Any, *arrays: FloatArray) -> FloatArray:
        batch = arrays[0].shape[:-1]
        flat = [np.reshape(a, (-1, self.n)) for a in arrays]
        out = [np.asarray(fn(*(a[i] for a in flat))) for i in range(flat[0].shape[0])]
        return np.reshape(np.stack(out), batch + out[0].shape)

    def _mass_matrix(self, q: FloatArray) -> FloatArray:
        def one(qi: FloatArray) -> FloatArray:
            m = self._pin.crba(self.model, self.data, qi)
            m = np.triu(m) + np.triu(m, 1).T  # crba fills the upper triangle
            return m + np.diag(self.J)
        return self._each(one, q)

    def _coriolis_matrix(self, q: FloatArray, qd: FloatArray) -> FloatArray:
        return self._each(lambda qi, vi: self._pin.computeCoriolisMatrix(self.model, self.data, qi, vi).copy(), q, qd)

    def _gravity(self, q: FloatArray) -> FloatArray:
        return self._each(lambda qi: self._pin.computeGeneralizedGravity(self.model, self.data, qi).copy(), q)

    def _bias(self, q: FloatArray, qd: FloatArray) -> tuple[FloatArray, FloatArray]:
        nle = self._each(lambda qi, vi: self._pin.nonLinearEffects(self.model, self.data, qi, vi).copy(), q, qd)
        return self._mass_matrix(q), nle

    def _potential(self, q: FloatArray) -> FloatArray:
        return self._each(lambda qi: np.array(self._pin.computePotentialEnergy(self.model, self.data, qi)), q)

    def _fk(self, q: FloatArray) -> FloatArray:
        def one(qi: FloatArray) -> FloatArray:
            self._pin.framesForwardKinematics(self.model, self.data, qi)
            return self.data.oMf[self.ee_id].translation.copy()
        return self._each(one, q)

    def position(self, q: FloatArray) -> FloatArray:
        return self._fk(q)

    def _jacobian(self, q: FloatArray) -> FloatArray:
        pin = self._pin

        def one(qi: FloatArray) -> FloatArray:
            jac = pin.computeFrameJacobian(self.model, self.data, qi, self.ee_id, pin.LOCAL_WORLD_ALIGNED)
            return jac[:3].copy()
        return self._each(one, q)

    def _ik(self, p: FloatArray) -> FloatArray:
        raise InvalidInputError(f"{self.name}: inverse kinematics of URDF robots is not built yet (issue 16)")
