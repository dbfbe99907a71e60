"""A MuJoCo model of an arm the project loads, built from the same description (ROS-free).

MuJoCo (PyPI ``mujoco``) is an independent physics engine: it is given the arm's
*description* -- the URDF our own model is built from (:func:`pdsmc_ros.robots.urdf.robot_urdf`
for the thesis arms, from ``config/robots.yaml``; the arm's URDF for a URDF arm) plus
the motor inertia, which URDF cannot express -- and never our matrices. MuJoCo's own
URDF parser reads the links' masses, centres of mass and inertia tensors, the joints'
axes and placements and ``<dynamics damping>``; :func:`build_model` then sets

* the motors' inertia ``J`` as MuJoCo's ``armature`` of each actuated joint (Eq. 4.1's
  ``Mbar = M + J``): ``motor_inertia`` of ``config/robots.yaml`` for the thesis arms,
  the ``armature`` option of a URDF arm;
* gravity along the URDF's -z (the thesis plane ``(x, y)`` is the URDF's ``(x, z)``),
  of the magnitude the description gives;
* no contacts (the arms' links pass through each other, as in Eq. 4.1);
* one motor per actuated joint (gear 1) whose force is limited to the URDF's
  ``<limit effort>`` when that is finite, as a drive saturates;
* RK4 with a step of the driver's period (or a fraction of it): the same integrator and
  zero-order hold as our own plant (:mod:`pdsmc_ros.sim.rk4`), so a comparison of the two
  isolates the models. The arms' damping is small (B = 0.07 N m s on J >= 0.05 kg m^2:
  a time constant of about a second), so an explicit integrator is stable at 1 kHz.

Joints locked by the arm's options (a gripper's fingers) become fixed joints at 0, which is
what Pinocchio's reduced model does. The thesis URDFs give the planar links' out-of-plane
inertia as a tiny placeholder, which violates the triangle inequality MuJoCo checks; for
those links the inertia about the link's long axis is kept and the other out-of-plane
moment is set to the in-plane one (a thin rod's), which cannot matter: every joint turns
about the same axis, so the angular velocity never has an out-of-plane component.

The five-bar is a closed chain (two distal links whose tips coincide); it is built as
its open tree plus an equality ``connect`` constraint (:func:`build_model`'s docstring says
how well MuJoCo's soft constraint matches our constrained model).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any
from xml.etree import ElementTree

import numpy as np
from numpy.typing import ArrayLike

from ..errors import InvalidInputError
from ..robots.base import FloatArray
from ..robots.catalog import resolve_robot
from ..robots.registry import make_robot, robot_params

THESIS_ARMS = ("serial_3r", "parallel_5r")
INTEGRATORS = ("rk4", "implicitfast", "euler")


def _mujoco() -> Any:
    try:
        import mujoco
    except ImportError as exc:  # pragma: no cover - pinned in requirements.txt
        raise InvalidInputError("the MuJoCo stand-in needs the 'mujoco' package: run make setup") from exc
    return mujoco


@dataclass(frozen=True)
class MujocoArm:
    """A compiled MuJoCo model of an arm and how its joints map to the robot's.

    Attributes
    ----------
    model : mujoco.MjModel
        The model (one motor per actuated joint, actuator ``i`` on ``joint_names[i]``).
    name : str
        The robot's name.
    joint_names : tuple of str
        Actuated joints in the robot's order.
    passive_joint_names : tuple of str
        Unactuated joints (the five-bar's distal joints), published too.
    qpos : ndarray of int
        ``qpos`` address of each joint of ``joint_names + passive_joint_names``.
    dof : ndarray of int
        ``qvel`` / ``qfrc`` address of each of those joints.
    effort_limits : ndarray
        Each actuated joint's effort limit (N m, ``inf``: none) the motors saturate at.
    urdf : str
        The URDF the model was built from (what ``/robot_description`` carries).
    """

    model: Any
    name: str
    joint_names: tuple[str, ...]
    passive_joint_names: tuple[str, ...]
    qpos: Any
    dof: Any
    effort_limits: FloatArray
    urdf: str

    @property
    def n(self) -> int:
        return len(self.joint_names)

    def data(self) -> Any:
        """A fresh ``mujoco.MjData`` of the model."""
        return _mujoco().MjData(self.model)


def description(robot: str) -> tuple[str, float, FloatArray | float, tuple[str, ...]]:
    """``(urdf, gravity, armature, locked_joints)`` of a registered robot: what both our model
    and MuJoCo's are built from."""
    try:
        return make_robot(resolve_robot(robot)).model_source()
    except InvalidInputError:
        raise InvalidInputError(f"robot {robot!r}: no description MuJoCo can load (a thesis arm or a URDF arm)"
                                ) from None


def mujoco_urdf(urdf: str, *, locked_joints: tuple[str, ...] = (), planar: bool = False) -> str:
    """The URDF as MuJoCo's parser is given it: no visuals or collisions (no meshes to find, no
    contacts), locked joints fixed at 0, and (``planar``) the placeholder out-of-plane inertia
    of the thesis URDFs made a thin rod's (module docstring)."""
    root = ElementTree.fromstring(urdf)
    for link in root.iter("link"):
        for tag in ("visual", "collision"):
            for element in link.findall(tag):
                link.remove(element)
        inertia = link.find("inertial/inertia")
        if planar and inertia is not None:
            iyy = float(inertia.get("iyy", "0"))
            inertia.set("izz", repr(iyy + float(inertia.get("ixx", "0"))))
    names = {joint.get("name") for joint in root.iter("joint")}
    for name in locked_joints:
        if name not in names:
            raise InvalidInputError(f"URDF: no joint {name!r} to lock")
    for joint in root.iter("joint"):
        if joint.get("name") in locked_joints:
            joint.set("type", "fixed")
            for tag in ("axis", "limit", "mimic", "dynamics", "safety_controller", "calibration"):
                for element in joint.findall(tag):
                    joint.remove(element)
    for mimic in [j for j in root.iter("joint") if j.find("mimic") is not None]:
        raise InvalidInputError(f"URDF: joint {mimic.get('name')!r} mimics another; lock it (locked_joints)")
    return ElementTree.tostring(root, encoding="unicode")


def effort_limits(urdf: str, joints: tuple[str, ...]) -> FloatArray:
    """``<limit effort>`` of each joint of the URDF (``inf`` where absent)."""
    root = ElementTree.fromstring(urdf)
    found: dict[str, float] = {}
    for joint in root.iter("joint"):
        limit = joint.find("limit")
        if limit is not None and limit.get("effort") is not None:
            found[str(joint.get("name"))] = float(limit.get("effort", "inf"))
    return np.array([found.get(j, np.inf) for j in joints], dtype=float)


def build_model(robot: str, *, timestep: float = 1e-3, integrator: str = "rk4") -> MujocoArm:
    """The MuJoCo model of a registered robot (module docstring).

    Parameters
    ----------
    robot : str
        ``serial_3r``, ``parallel_5r``, a named URDF arm or a ``.urdf`` path
        (:func:`pdsmc_ros.robots.catalog.resolve_robot`).
    timestep : float
        MuJoCo's step (s).
    integrator : str
        ``rk4`` (default), ``implicitfast`` or ``euler``.

    Raises
    ------
    InvalidInputError
        An unknown robot (naming what is allowed), a URDF MuJoCo refuses (one line, its reason), a bad step.
    """
    mujoco = _mujoco()
    if not np.isfinite(timestep) or timestep <= 0.0:
        raise InvalidInputError(f"timestep must be > 0 s, got {timestep!r}")
    if integrator not in INTEGRATORS:
        raise InvalidInputError(f"integrator must be one of {', '.join(INTEGRATORS)}, got {integrator!r}")
    ours = make_robot(resolve_robot(robot))
    urdf, gravity, armature, locked = description(robot)
    joints = tuple(ours.joint_names)
    passive = tuple(ours.passive_joint_names)
    try:
        spec = mujoco.MjSpec.from_string(mujoco_urdf(urdf, locked_joints=locked, planar=robot in THESIS_ARMS))
    except ValueError as exc:
        raise InvalidInputError(f"robot {robot!r}: MuJoCo cannot read its URDF: {_first_line(exc)}") from None
    spec.option.gravity = [0.0, 0.0, -gravity]
    spec.option.timestep = timestep
    spec.option.integrator = {"rk4": mujoco.mjtIntegrator.mjINT_RK4,
                              "implicitfast": mujoco.mjtIntegrator.mjINT_IMPLICITFAST,
                              "euler": mujoco.mjtIntegrator.mjINT_EULER}[integrator]
    spec.option.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_CONTACT)
    known = {j.name for j in spec.joints}
    missing = [j for j in joints + passive if j not in known]
    if missing:
        raise InvalidInputError(f"robot {robot!r}: MuJoCo's model has no joint {missing[0]!r}")
    j = np.broadcast_to(np.asarray(armature, dtype=float), (len(joints),))
    limits = effort_limits(urdf, joints)
    for name, inertia, limit in zip(joints, j, limits, strict=True):
        spec.joint(name).armature = float(inertia)
        motor = spec.add_actuator(name=f"{name}_motor", target=name, trntype=mujoco.mjtTrn.mjTRN_JOINT)
        motor.set_to_motor()
        if np.isfinite(limit):
            motor.forcelimited = mujoco.mjtLimited.mjLIMITED_TRUE
            motor.forcerange = [-float(limit), float(limit)]
    if robot == "parallel_5r":
        _close_five_bar(spec, mujoco, robot_params(robot))
    try:
        model = spec.compile()
    except ValueError as exc:
        raise InvalidInputError(f"robot {robot!r}: MuJoCo refuses the model: {_first_line(exc)}") from None
    ids = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name) for name in joints + passive]
    return MujocoArm(model=model, name=robot, joint_names=joints, passive_joint_names=passive,
                     qpos=np.array([model.jnt_qposadr[i] for i in ids], dtype=np.intp),
                     dof=np.array([model.jnt_dofadr[i] for i in ids], dtype=np.intp),
                     effort_limits=limits, urdf=urdf)


def _close_five_bar(spec: Any, mujoco: Any, params: Any) -> None:
    """The five-bar's loop closure: the tips of link3 and link4 coincide (an equality ``connect``
    between a site at each tip), as stiff as MuJoCo's soft constraints allow at the step."""
    tips = []
    for link, length in (("link3", params.links[2].length), ("link4", params.links[3].length)):
        body = spec.body(link)
        tips.append(body.add_site(name=f"{link}_tip", pos=[length, 0.0, 0.0]))
    eq = spec.add_equality(type=mujoco.mjtEq.mjEQ_CONNECT, objtype=mujoco.mjtObj.mjOBJ_SITE,
                           name1="link3_tip", name2="link4_tip")
    eq.solref = [2.0 * spec.option.timestep, 1.0]
    eq.solimp = [0.9999, 0.9999, 0.001, 0.5, 2.0]


def _first_line(exc: BaseException) -> str:
    text = str(exc).strip()
    return " ".join(text.splitlines()[:2]) if text else type(exc).__name__


def set_state(arm: MujocoArm, data: Any, q: ArrayLike, qd: ArrayLike | None = None) -> None:
    """Put the actuated joints at ``q`` (rates ``qd``, default 0); passive joints are left."""
    n = arm.n
    data.qpos[arm.qpos[:n]] = np.asarray(q, dtype=float)
    data.qvel[arm.dof[:n]] = 0.0 if qd is None else np.asarray(qd, dtype=float)


def mass_matrix(arm: MujocoArm, data: Any) -> FloatArray:
    """MuJoCo's joint-space inertia at ``data.qpos`` (armature included), actuated joints, robot
    order (``mj_fullM`` of the sparse inertia after ``mj_forward``)."""
    mujoco = _mujoco()
    mujoco.mj_forward(arm.model, data)
    full = np.zeros((arm.model.nv, arm.model.nv))
    mujoco.mj_fullM(arm.model, data, full)
    d = arm.dof[:arm.n]
    return full[np.ix_(d, d)]


def bias_forces(arm: MujocoArm, data: Any) -> FloatArray:
    """MuJoCo's ``qfrc_bias`` (Coriolis, centrifugal and gravity) minus its passive forces (the
    joints' damping enters as ``-b qd``), so it compares with ``C qd + G + B qd``."""
    mujoco = _mujoco()
    mujoco.mj_forward(arm.model, data)
    d = arm.dof[:arm.n]
    return np.asarray(data.qfrc_bias[d] - data.qfrc_passive[d], dtype=float)
