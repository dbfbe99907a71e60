"""URDF robots through Pinocchio (issue 16's first part): the thesis's serial arm from its URDF
has the built-in model's dynamics; bad URDFs are one line."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("pinocchio")

from pdsmc_ros.errors import InvalidInputError  # noqa: E402
from pdsmc_ros.robots import Serial3R, robot_params  # noqa: E402
from pdsmc_ros.robots.urdf_robot import from_urdf  # noqa: E402
from pdsmc_ros.urdf import robot_urdf  # noqa: E402

PARAMS = robot_params("serial_3r")


def serial_from_urdf(tmp_path: Path):  # noqa: ANN201
    path = tmp_path / "serial_3r.urdf"
    path.write_text(robot_urdf("serial_3r", PARAMS))
    return from_urdf(path, armature=PARAMS.motor_inertia, ee_frame="tool0")


def test_the_serial_arm_from_its_urdf_has_the_built_in_dynamics(tmp_path: Path) -> None:
    urdf, built_in = serial_from_urdf(tmp_path), Serial3R()
    assert urdf.joint_names == ("joint1", "joint2", "joint3") and urdf.n == 3
    np.testing.assert_array_equal(urdf.B, built_in.B)  # <dynamics damping> is the motor damping
    rng = np.random.default_rng(16)
    for _ in range(20):
        q, qd, tau = rng.uniform(-3, 3, 3), rng.uniform(-2, 2, 3), rng.uniform(-20, 20, 3)
        np.testing.assert_allclose(urdf.mass_matrix(q), built_in.mass_matrix(q), rtol=0, atol=1e-9)
        np.testing.assert_allclose(urdf.coriolis_matrix(q, qd) @ qd, built_in.coriolis_matrix(q, qd) @ qd,
                                   rtol=0, atol=1e-9)
        np.testing.assert_allclose(urdf.gravity(q), built_in.gravity(q), rtol=0, atol=1e-9)
        np.testing.assert_allclose(urdf.forward_dynamics(q, qd, tau), built_in.forward_dynamics(q, qd, tau),
                                   rtol=0, atol=1e-9)
        # the thesis plane (x, y) is the URDF's (x, z)
        x, y, z = urdf.forward_kinematics(q)
        np.testing.assert_allclose([x, z], built_in.position(q), rtol=0, atol=1e-12)
        assert abs(y) < 1e-12
        np.testing.assert_allclose(urdf.jacobian(q)[[0, 2]], built_in.jacobian(q)[:2], rtol=0, atol=1e-12)
    q = rng.uniform(-3, 3, (4, 3))  # a batch, as the built-in robots take
    np.testing.assert_allclose(urdf.mass_matrix(q), built_in.mass_matrix(q), rtol=0, atol=1e-9)
    np.testing.assert_array_equal(urdf.torque_limit, [1e6] * 3)


def test_bad_urdfs_are_one_line_naming_the_problem(tmp_path: Path) -> None:
    broken = tmp_path / "broken.urdf"
    broken.write_text("<robot name='x'><link name='a'></robot>")
    with pytest.raises(InvalidInputError, match="does not parse") as info:
        from_urdf(broken)
    assert "\n" not in str(info.value) and "broken.urdf" in str(info.value)
    with pytest.raises(InvalidInputError, match="no such file"):
        from_urdf(tmp_path / "missing.urdf")
    fixed_only = ("<robot name='f'><link name='a'/><link name='b'/><joint name='j' type='fixed'>"
                  "<parent link='a'/><child link='b'/></joint></robot>")
    with pytest.raises(InvalidInputError, match="no movable joint"):
        from_urdf(fixed_only)
    with pytest.raises(InvalidInputError, match="no frame 'hand'"):
        from_urdf(robot_urdf("serial_3r", PARAMS), ee_frame="hand")
    massless = robot_urdf("serial_3r", PARAMS).replace('<mass value="0.5"/>', '<mass value="0.0"/>')
    with pytest.raises(InvalidInputError, match=r"no mass"):
        from_urdf(massless)
    with pytest.raises(InvalidInputError, match="armature must be 3 finite values"):
        from_urdf(robot_urdf("serial_3r", PARAMS), armature=[-1.0, 0.0, 0.0])
