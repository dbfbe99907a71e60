"""The compiled serial chain (spatial_layout, _kernels, _dynamics) against Pinocchio: mass matrix, bias, gravity,
Christoffel Coriolis product, end-effector pose and Jacobian, on the sample manipulator, the thesis's
planar arm, the UR5, the Panda and a chain with prismatic joints; and what pack refuses."""

from __future__ import annotations

import importlib.metadata
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

pin = pytest.importorskip("pinocchio")

from pdsmc_ros.robots import robot_params  # noqa: E402
from pdsmc_ros.robots import spatial_dynamics as dyn  # noqa: E402
from pdsmc_ros.robots import spatial_kernels as kin  # noqa: E402
from pdsmc_ros.robots import spatial_layout as lay  # noqa: E402
from pdsmc_ros.robots.urdf import robot_urdf  # noqa: E402

TOL = 1e-10
SAMPLES = 20
SENTINEL = 12345.678  # what the scratch beyond workspace_size(n) must still hold afterwards


def robots_dir() -> Path:
    try:
        dist = importlib.metadata.distribution("example-robot-data")
    except importlib.metadata.PackageNotFoundError:
        pytest.skip("example-robot-data is not installed")
    return Path(str(dist.locate_file("cmeel.prefix/share/example-robot-data/robots")))


def sample_manipulator() -> tuple[Any, str]:
    return pin.buildSampleModelManipulator(), "effector_body"


def planar_arm() -> tuple[Any, str]:
    # the URDF's axes are "0 -1 0": Pinocchio makes them RevoluteUnaligned
    return pin.buildModelFromXML(robot_urdf("serial_3r", robot_params("serial_3r"), 0.0)), "tool0"


def ur5() -> tuple[Any, str]:
    return pin.buildModelFromUrdf(str(robots_dir() / "ur_description/urdf/ur5_robot.urdf")), "tool0"


def panda() -> tuple[Any, str]:
    full = pin.buildModelFromUrdf(str(robots_dir() / "panda_description/urdf/panda.urdf"))
    fingers = [full.getJointId("panda_finger_joint1"), full.getJointId("panda_finger_joint2")]
    return pin.buildReducedModel(full, fingers, pin.neutral(full)), "panda_hand_tcp"


def random_placement(rng: np.random.Generator) -> Any:
    return pin.SE3(pin.exp3(rng.normal(size=3)), rng.uniform(-0.3, 0.3, 3))


def random_inertia(rng: np.random.Generator) -> Any:
    root = 0.2 * rng.normal(size=(3, 3))
    return pin.Inertia(rng.uniform(0.5, 3.0), rng.uniform(-0.15, 0.15, 3), root @ root.T + 0.01 * np.eye(3))


def unit(v: list[float]) -> np.ndarray:
    return np.asarray(v, dtype=float) / np.linalg.norm(v)


def mixed_chain() -> tuple[Any, str]:
    """Revolute and prismatic joints, aligned and not, random placements and bodies, odd gravity."""
    rng = np.random.default_rng(7)
    model = pin.Model()
    joints = [pin.JointModelRZ(), pin.JointModelPrismaticUnaligned(unit([0.3, -0.5, 0.8])),
              pin.JointModelRevoluteUnaligned(unit([-0.2, 0.9, 0.4])), pin.JointModelPX(), pin.JointModelRY(),
              pin.JointModelPZ()]
    parent = 0
    for k, joint in enumerate(joints):
        parent = model.addJoint(parent, joint, random_placement(rng), f"joint{k + 1}")
        model.appendBodyToJoint(parent, random_inertia(rng), pin.SE3.Identity())
    model.addFrame(pin.Frame("tool", parent, random_placement(rng), pin.FrameType.OP_FRAME))
    model.addFrame(pin.Frame("middle", 3, random_placement(rng), pin.FrameType.OP_FRAME))
    model.addFrame(pin.Frame("on_base", 0, random_placement(rng), pin.FrameType.OP_FRAME))
    model.gravity = pin.Motion(np.array([1.0, -2.0, -9.0]), np.zeros(3))
    return model, "tool"


MODELS: dict[str, Callable[[], tuple[Any, str]]] = {
    "sample_manipulator": sample_manipulator,
    "planar_arm": planar_arm,
    "ur5": ur5,
    "panda": panda,
    "mixed_chain": mixed_chain,
}


def scratch(n: int) -> np.ndarray:
    """``workspace_size(n)`` floats and a tail of sentinels, to catch writes beyond it."""
    return np.full(lay.workspace_size(n) + 8, SENTINEL)


def close(got: np.ndarray, want: np.ndarray) -> None:
    np.testing.assert_allclose(got, want, rtol=TOL, atol=TOL)


class Reference:
    """Pinocchio's answers for one model and end-effector frame."""

    def __init__(self, model: Any, frame: str) -> None:
        self.model = model
        self.data = model.createData()
        self.fid = model.getFrameId(frame)
        self.still = pin.Model(model)  # gravity off: nle is then C(q, x) x
        self.still.gravity = pin.Motion.Zero()
        self.still_data = self.still.createData()

    def mass(self, q: np.ndarray) -> np.ndarray:
        upper = np.triu(pin.crba(self.model, self.data, q))  # Pinocchio fills the upper triangle
        return upper + np.triu(upper, 1).T

    def nle(self, q: np.ndarray, qd: np.ndarray) -> np.ndarray:
        return pin.nonLinearEffects(self.model, self.data, q, qd).copy()

    def gravity(self, q: np.ndarray) -> np.ndarray:
        return pin.computeGeneralizedGravity(self.model, self.data, q).copy()

    def coriolis_times(self, q: np.ndarray, qd: np.ndarray, v: np.ndarray) -> np.ndarray:
        c = pin.nonLinearEffects
        return 0.25 * (c(self.still, self.still_data, q, qd + v) - c(self.still, self.still_data, q, qd - v))

    def pose(self, q: np.ndarray, fid: int) -> tuple[np.ndarray, np.ndarray]:
        pin.framesForwardKinematics(self.model, self.data, q)
        placement = self.data.oMf[fid]
        return placement.translation.copy(), placement.rotation.copy()

    def jacobian(self, q: np.ndarray, fid: int) -> np.ndarray:
        return pin.computeFrameJacobian(self.model, self.data, q, fid, pin.LOCAL_WORLD_ALIGNED).copy()


def packed(model: Any, frame: str | int, armature: Any = 0.0, damping: Any = 0.0) -> np.ndarray:
    fid = frame if isinstance(frame, int) else model.getFrameId(frame)
    return lay.pack(model, armature, damping, fid, [0.1, -0.2, 0.3], unit([1.0, 0.0, 1.0]), [0.0, 1.0, 0.0])


@pytest.mark.parametrize("name", list(MODELS))
def test_the_dynamics_are_pinocchios(name: str) -> None:
    model, frame = MODELS[name]()
    assert not np.any(model.armature)  # Pinocchio's crba would add it
    n = model.nv
    ref = Reference(model, frame)
    armature = np.linspace(0.05, 0.3, n)
    p = packed(model, frame, armature, np.linspace(0.5, 1.0, n))
    assert p[lay.N_JOINTS] == n and p.shape == (lay.HEADER_SIZE + n * lay.JOINT_SIZE,)
    work = scratch(n)
    mass, bias, g, cv, cqd = np.empty((n, n)), np.empty(n), np.empty(n), np.empty(n), np.empty(n)
    rng = np.random.default_rng(2024)
    for _ in range(SAMPLES):
        q = rng.uniform(-np.pi, np.pi, n)
        qd, v = rng.uniform(-3.0, 3.0, (2, n))
        dyn.terms(p, q, qd, mass, bias, work)
        dyn.gravity(p, q, g, work)
        dyn.coriolis_times(p, q, qd, v, cv, work)
        dyn.coriolis_times(p, q, qd, qd, cqd, work)
        np.testing.assert_array_equal(mass, mass.T)
        close(mass - np.diag(armature), ref.mass(q))
        close(bias, ref.nle(q, qd))
        close(g, ref.gravity(q))
        close(cv, ref.coriolis_times(q, qd, v))
        close(cqd, ref.nle(q, qd) - ref.gravity(q))  # C(q, qd) qd is the bias without gravity
        assert np.all(np.linalg.eigvalsh(mass) > 0.0)
        np.linalg.cholesky(mass)
    np.testing.assert_array_equal(work[-8:], SENTINEL)


@pytest.mark.parametrize("name", list(MODELS))
def test_the_end_effector_is_pinocchios(name: str) -> None:
    model, frame = MODELS[name]()
    n = model.nv
    ref = Reference(model, frame)
    p = packed(model, frame)
    origin, u, v = p[lay.PLANE_ORIGIN:][:3], p[lay.PLANE_U:][:3], p[lay.PLANE_V:][:3]
    work = scratch(n)
    pos, pos2, rot, jac = np.empty(3), np.empty(3), np.empty((3, 3)), np.empty((6, n))
    rng = np.random.default_rng(99)
    for _ in range(SAMPLES):
        q = rng.uniform(-np.pi, np.pi, n)
        kin.ee_position(p, q, pos, work)
        kin.ee_pose(p, q, pos2, rot, work)
        kin.ee_jacobian(p, q, jac, work)
        out = np.full(6, 7.0)
        kin.outputs(p, q, q, out, work)
        want_pos, want_rot = ref.pose(q, ref.fid)
        close(pos, want_pos)
        np.testing.assert_array_equal(pos2, pos)
        close(rot, want_rot)
        close(jac, ref.jacobian(q, ref.fid))
        close(out[:2], [(want_pos - origin) @ u, (want_pos - origin) @ v])
        np.testing.assert_array_equal(out[2:], 7.0)  # outputs writes only the plane coordinates
    np.testing.assert_array_equal(work[-8:], SENTINEL)


@pytest.mark.parametrize("frame", ["middle", "on_base"])
def test_frames_before_the_last_joint(frame: str) -> None:
    model, _ = mixed_chain()
    n = model.nv
    ref = Reference(model, frame)
    p = packed(model, frame)
    assert p[lay.EE_JOINT] == model.frames[ref.fid].parentJoint
    work = scratch(n)
    pos, rot, jac = np.empty(3), np.empty((3, 3)), np.empty((6, n))
    rng = np.random.default_rng(5)
    for _ in range(SAMPLES):
        q = rng.uniform(-np.pi, np.pi, n)
        kin.ee_pose(p, q, pos, rot, work)
        kin.ee_jacobian(p, q, jac, work)
        want_pos, want_rot = ref.pose(q, ref.fid)
        close(pos, want_pos)
        close(rot, want_rot)
        close(jac, ref.jacobian(q, ref.fid))
    assert not np.any(jac[:, int(p[lay.EE_JOINT]):])  # joints after the frame's do not move it


def test_armature_and_damping() -> None:
    model, frame = sample_manipulator()
    n = model.nv
    armature, damping = np.arange(1.0, n + 1.0) / 10, np.arange(1.0, n + 1.0) / 4
    p, bare = packed(model, frame, armature, damping), packed(model, frame)
    work = scratch(n)
    q, qd = np.linspace(-1.0, 1.0, n), np.linspace(2.0, -1.0, n)
    with_motors, without, bias, bias_bare = np.empty((n, n)), np.empty((n, n)), np.empty(n), np.empty(n)
    dyn.terms(p, q, qd, with_motors, bias, work)
    dyn.terms(bare, q, qd, without, bias_bare, work)
    close(with_motors - without, np.diag(armature))
    np.testing.assert_array_equal(bias, bias_bare)  # damping is not in the bias
    assert [dyn.motor_inertia(p, i) for i in range(n)] == list(armature)
    assert [dyn.damping(p, i) for i in range(n)] == list(damping)
    scalar = packed(model, frame, 0.5, 2.0)
    assert [dyn.motor_inertia(scalar, i) for i in range(n)] == [0.5] * n
    assert [dyn.damping(scalar, i) for i in range(n)] == [2.0] * n


def test_the_scratch_fits_the_compiled_modules_workspace() -> None:
    from pdsmc_ros.robots.compiled import workspace

    for n in range(1, 13):
        # forward_dynamics hands terms what is left after 2 n + n^2 floats
        assert lay.workspace_size(n) <= workspace(n).size - 2 * n - n * n


def add_chain(model: Any, joints: list[Any], parent: int = 0) -> int:
    for joint in joints:
        parent = model.addJoint(parent, joint, pin.SE3.Identity(), f"j{model.njoints}")
        model.appendBodyToJoint(parent, pin.Inertia.FromSphere(1.0, 0.1), pin.SE3.Identity())
    return parent


def test_pack_refuses_trees_and_other_joints() -> None:
    tree = pin.Model()
    add_chain(tree, [pin.JointModelRZ(), pin.JointModelRY()])
    add_chain(tree, [pin.JointModelRX()], parent=1)  # a second child of joint 1
    with pytest.raises(ValueError, match="not a serial chain"):
        packed(tree, 0)
    for odd in (pin.JointModelFreeFlyer(), pin.JointModelSpherical(), pin.JointModelRUBZ(), pin.JointModelHZ(0.1)):
        model = pin.Model()
        add_chain(model, [pin.JointModelRZ(), odd, pin.JointModelRY()])
        with pytest.raises(ValueError, match="revolute and prismatic"):
            packed(model, 0)
    with pytest.raises(ValueError, match="no joint"):
        packed(pin.Model(), 0)


def test_pack_refuses_the_panda_with_its_fingers() -> None:
    full = pin.buildModelFromUrdf(str(robots_dir() / "panda_description/urdf/panda.urdf"))
    with pytest.raises(ValueError, match="not a serial chain"):
        packed(full, "panda_hand_tcp")


def test_pack_refuses_bad_arguments() -> None:
    model, frame = sample_manipulator()
    n, fid = model.nv, model.getFrameId(frame)
    plane = ([0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0])
    with pytest.raises(ValueError, match="armature"):
        lay.pack(model, np.ones(n - 1), 0.0, fid, *plane)
    with pytest.raises(ValueError, match="damping"):
        lay.pack(model, 0.0, -np.ones(n), fid, *plane)
    with pytest.raises(ValueError, match="no frame"):
        lay.pack(model, 0.0, 0.0, model.nframes, *plane)
    with pytest.raises(ValueError, match="orthonormal"):
        lay.pack(model, 0.0, 0.0, fid, [0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0])
    with pytest.raises(ValueError, match="plane_origin"):
        lay.pack(model, 0.0, 0.0, fid, [0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0])
    crooked = pin.Model()
    add_chain(crooked, [pin.JointModelRevoluteUnaligned(np.array([0.0, 1.0, 1.0]))])  # not normalised
    with pytest.raises(ValueError, match="non-unit axis"):
        packed(crooked, 0)
