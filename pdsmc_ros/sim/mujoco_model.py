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

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any
from xml.etree import ElementTree

import numpy as np
from numpy.typing import ArrayLike

from ..errors import InvalidInputError
from ..robots.base import FloatArray, Manipulator
from ..robots.catalog import resolve_robot
from ..robots.registry import make_robot, robot_params
from .realism import ArmFacts, Realism, resolve_realism

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
    urdf_damping: FloatArray | None = None
    """Each actuated joint's damping (N m s/rad) as the description gives it (``<dynamics damping>``):
    what :func:`set_friction` adds the stand-in's viscous friction to."""
    urdf_frictionloss: FloatArray | None = None
    """Each actuated joint's dry friction (N m) as the description gives it (``<dynamics friction>``)."""

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


def build_model(robot: str, *, timestep: float = 1e-3, integrator: str = "rk4", source: Manipulator | None = None,
                payload: tuple[float, ArrayLike] | None = None) -> MujocoArm:
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
    source : Manipulator, optional
        Build from this robot's description instead of the registered one's (a plant drawn around
        it: :mod:`pdsmc_ros.experiments.montecarlo`).
    payload : (float, array_like), optional
        A load the controller's model does not know: its mass (kg) and centre of mass (m, in the
        arm's tool frame), a fixed link of the description MuJoCo is given (:func:`payload_urdf`).

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
    ours = make_robot(resolve_robot(robot)) if source is None else source
    urdf, gravity, armature, locked = description(robot) if source is None else source.model_source()
    joints = tuple(ours.joint_names)
    passive = tuple(ours.passive_joint_names)
    given = urdf
    if payload is not None and payload[0] > 0.0:
        given = payload_urdf(urdf, tool_frame(ours), *payload)
    try:
        spec = mujoco.MjSpec.from_string(mujoco_urdf(given, locked_joints=locked, planar=robot in THESIS_ARMS))
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
        _close_five_bar(spec, mujoco, robot_params(robot) if source is None else source.params)
    try:
        model = spec.compile()
    except ValueError as exc:
        raise InvalidInputError(f"robot {robot!r}: MuJoCo refuses the model: {_first_line(exc)}") from None
    ids = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name) for name in joints + passive]
    dof = np.array([model.jnt_dofadr[i] for i in ids], dtype=np.intp)
    return MujocoArm(model=model, name=robot, joint_names=joints, passive_joint_names=passive,
                     qpos=np.array([model.jnt_qposadr[i] for i in ids], dtype=np.intp),
                     dof=dof, effort_limits=limits, urdf=urdf,
                     urdf_damping=model.dof_damping[dof[:len(joints)]].copy(),
                     urdf_frictionloss=model.dof_frictionloss[dof[:len(joints)]].copy())


def tool_frame(robot: Manipulator) -> str:
    """The link of the arm's tool frame: a URDF arm's ``ee_frame``, a thesis arm's ``tool0`` (the
    tip of its last link, its axes)."""
    return str(getattr(robot, "ee_frame", None) or "tool0")


def payload_urdf(urdf: str, frame: str, mass: float, com: ArrayLike) -> str:
    """The URDF with a point mass of ``mass`` kg fixed at ``com`` (m) in the link ``frame`` (or the
    child link of the joint ``frame``): a load MuJoCo's parser fuses into the link that carries it,
    as it fuses every fixed link.

    Raises
    ------
    InvalidInputError
        If the URDF has no link or joint ``frame``, or the mass or position is not finite.
    """
    offset = np.asarray(com, dtype=float).reshape(-1)
    if not (np.isfinite(mass) and mass >= 0.0) or offset.shape != (3,) or not np.all(np.isfinite(offset)):
        raise InvalidInputError(f"payload: a mass >= 0 kg and 3 finite coordinates (m), got {mass!r}, {com!r}")
    root = ElementTree.fromstring(urdf)
    links = {link.get("name") for link in root.iter("link")}
    parent = frame
    if frame not in links:
        joint = next((j for j in root.iter("joint") if j.get("name") == frame), None)
        child = None if joint is None else joint.find("child")
        if child is None:
            raise InvalidInputError(f"payload: the URDF has no link or joint {frame!r} (the tool frame)")
        parent = str(child.get("link"))
    name = "pdsmc_payload"
    while name in links:
        name += "_"
    xyz = " ".join(repr(float(v)) for v in offset)
    joint = ElementTree.SubElement(root, "joint", {"name": f"{name}_joint", "type": "fixed"})
    ElementTree.SubElement(joint, "parent", {"link": parent})
    ElementTree.SubElement(joint, "child", {"link": name})
    ElementTree.SubElement(joint, "origin", {"xyz": xyz, "rpy": "0 0 0"})
    link = ElementTree.SubElement(root, "link", {"name": name})
    inertial = ElementTree.SubElement(link, "inertial")
    ElementTree.SubElement(inertial, "origin", {"xyz": "0 0 0", "rpy": "0 0 0"})
    ElementTree.SubElement(inertial, "mass", {"value": repr(float(mass))})
    ElementTree.SubElement(inertial, "inertia", dict.fromkeys(("ixx", "ixy", "ixz", "iyy", "iyz", "izz"), "0"))
    return ElementTree.tostring(root, encoding="unicode")


FRICTION_SOLIMP = (0.9999, 0.9999, 0.001, 0.5, 2.0)
"""The dry friction's impedance: with MuJoCo's default (0.9) a joint pushed by 90 % of its
Coulomb friction creeps at a tenth of the acceleration it would have unresisted, over the
constraint's damping (a UR5 wrist, 0.012 rad/s); at 0.9999 the creep is a ten-thousandth of it
and the joint sticks, as Coulomb friction holds it (test/sim/test_drive.py)."""


def set_friction(arm: MujocoArm, coulomb: ArrayLike, viscous: ArrayLike) -> None:
    """Give the actuated joints Coulomb and viscous friction (N m, N m s/rad) on top of the
    description's, in the compiled model (it may change between steps).

    MuJoCo's dry friction (``frictionloss``) is a soft constraint; with its default
    ``solref_friction`` (0.02 s) it is far from Coulomb friction (the UR5's identified 5 N m read
    back as 4.3-4.8 N m, its viscous term up to twice what was set); a time constant of two
    timesteps makes it read back within 2 %, so every actuated joint gets that, and an impedance of
    :data:`FRICTION_SOLIMP` so that a joint pushed below its friction sticks. A joint's damping is
    the description's plus ``viscous``.
    """
    model = arm.model
    dof = arm.dof[:arm.n]
    base_damping = arm.urdf_damping if arm.urdf_damping is not None else np.zeros(arm.n)
    base_friction = arm.urdf_frictionloss if arm.urdf_frictionloss is not None else np.zeros(arm.n)
    model.dof_frictionloss[dof] = base_friction + np.asarray(coulomb, dtype=float)
    model.dof_damping[dof] = base_damping + np.asarray(viscous, dtype=float)
    model.dof_solref[dof] = [2.0 * float(model.opt.timestep), 1.0]
    model.dof_solimp[dof] = FRICTION_SOLIMP


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


def arm_facts(arm: MujocoArm, robot: Manipulator, rate: float) -> ArmFacts:
    """What sizing the stand-in's nuisances needs (:class:`~.realism.ArmFacts`): the robot's joint
    limits (those its controller clamps to), which joints turn, the mass of MuJoCo's moving bodies
    (those not welded to the world), and the driver's rate."""
    mujoco = _mujoco()
    model = arm.model
    ids = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name) for name in arm.joint_names]
    revolute = np.array([model.jnt_type[i] == mujoco.mjtJoint.mjJNT_HINGE for i in ids], dtype=bool)
    moving = float(np.sum(model.body_mass[model.body_weldid != 0]))
    return ArmFacts(joint_names=arm.joint_names, effort_limits=np.asarray(robot.effort_limits, dtype=float),
                    velocity_limits=np.asarray(robot.velocity_limits, dtype=float), revolute=revolute,
                    moving_mass=moving, rate=float(rate))


def build_stand_in(robot: str, *, rate: float, substeps: int = 1, preset: str = "ideal",
                   given: Mapping[str, Any] | None = None, seed: int = 0, source: Manipulator | None = None,
                   integrator: str = "rk4") -> tuple[MujocoArm, Realism, ArmFacts]:
    """The stand-in's MuJoCo model and its nuisances, resolved for the arm (one place for the
    driver node and the lockstep runs): the model at a step of ``1 / rate / substeps``, the
    nuisances of ``preset`` with ``given`` replacing theirs (:func:`~.realism.resolve_realism`),
    the payload in the description and the friction on the joints. Also the facts they were sized
    from (:func:`arm_facts` of the arm without the payload): what new values are resolved against.

    Raises
    ------
    InvalidInputError
        A robot MuJoCo cannot load; :class:`~.realism.RealismError` for a nuisance refused.
    """
    if not (np.isfinite(rate) and rate > 0.0):
        raise InvalidInputError(f"rate must be > 0 Hz, got {rate!r}")
    if int(substeps) < 1:
        raise InvalidInputError(f"substeps must be >= 1, got {substeps!r}")
    ours = make_robot(resolve_robot(robot)) if source is None else source
    timestep = 1.0 / rate / int(substeps)
    arm = build_model(robot, timestep=timestep, integrator=integrator, source=source)
    facts = arm_facts(arm, ours, rate)
    realism = resolve_realism(facts, preset, given, seed=seed)
    if realism.payload_mass > 0.0:
        arm = build_model(robot, timestep=timestep, integrator=integrator, source=source,
                          payload=(realism.payload_mass, realism.payload_com))
    set_friction(arm, realism.friction_coulomb, realism.friction_viscous)
    return arm, realism, facts
