"""The driver around MuJoCo, without ROS: brakes, commands by joint name, drops, timeout, wall clock."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from pdsmc_ros.errors import InvalidInputError

pytest.importorskip("mujoco")

from pdsmc_ros.mujoco_driver import driver as md  # noqa: E402
from pdsmc_ros.parameters.tables import DEFAULT_COMMAND_TIMEOUT_S  # noqa: E402
from pdsmc_ros.sim.mujoco_model import MujocoArm, build_model  # noqa: E402


@pytest.fixture(scope="module")
def arm() -> MujocoArm:
    return build_model("serial_3r", timestep=1e-3)


def driver(arm: MujocoArm, **kwargs: object) -> md.MujocoDriver:
    """A driver that holds the last command as a forward command controller does (no watchdog),
    unless the test gives ``command_timeout``."""
    kwargs.setdefault("command_timeout", 0.0)
    return md.MujocoDriver(arm, md.default_positions("serial_3r"), **kwargs)  # type: ignore[arg-type]


def test_the_stand_in_brakes_after_a_tenth_of_a_second_without_a_command_by_default(arm: MujocoArm) -> None:
    d = md.MujocoDriver(arm, md.default_positions("serial_3r"))
    assert d.command_timeout == DEFAULT_COMMAND_TIMEOUT_S == 0.1
    d.command([0.0, 0.0, 0.0], 1.0)
    d.advance(1.05)
    assert not d.braked
    assert d.advance(1.11) and d.braked


def test_braked_until_the_first_command_then_it_moves(arm: MujocoArm) -> None:
    d = driver(arm)
    q0, _, _ = d.state()
    for t in np.arange(0.0, 0.3, 0.001):
        d.advance(float(t))
    q, qd, effort = d.state()
    assert d.braked and d.steps == 0
    np.testing.assert_array_equal(q, q0)
    np.testing.assert_array_equal(qd, 0.0)
    np.testing.assert_array_equal(effort, 0.0)
    assert d.command([0.0, 0.0, 0.0], 1.0) is None  # released at t = 1 s: a zero torque, so the arm falls
    for k in range(1, 201):
        d.advance(1.0 + k * 1e-3)
    q, qd, _ = d.state()
    assert not d.braked and d.steps == 200
    assert np.all(np.abs(q - q0) > 1e-3) and np.all(qd != 0.0)


def test_the_command_is_held_and_applied_by_joint_name(arm: MujocoArm) -> None:
    in_order = driver(arm)
    reversed_ = driver(arm, command_joints=["joint3", "joint2", "joint1"])
    in_order.command([1.0, -2.0, 3.0], 0.0)
    reversed_.command([3.0, -2.0, 1.0], 0.0)
    for t in (0.05, 0.1):  # no new command: the last one is applied on
        in_order.advance(t)
        reversed_.advance(t)
    a, b = in_order.state(), reversed_.state()
    for x, y in zip(a, b, strict=True):
        np.testing.assert_array_equal(x, y)
    np.testing.assert_array_equal(a[2], [1.0, -2.0, 3.0])  # effort: the motors' torque, robot order


def test_a_bad_command_is_dropped_and_the_last_good_one_stays(arm: MujocoArm) -> None:
    d = driver(arm)
    assert "2 values for 3 joints" in str(d.command([1.0, 2.0], 0.0))
    assert d.braked  # a dropped command does not release the brakes
    d.command([1.0, 2.0, 3.0], 0.0)
    why = d.command([1.0, float("nan"), 3.0], 0.01)
    assert why is not None and "'joint2'" in why and "non-finite" in why
    assert d.dropped == 2 and d.commands == 1
    d.advance(0.02)
    np.testing.assert_array_equal(d.state()[2], [1.0, 2.0, 3.0])


def test_effort_saturates_at_the_urdf_limit() -> None:
    arm = build_model("ur5")
    d = md.MujocoDriver(arm, md.default_positions("ur5"))
    d.command([500.0, -500.0, 10.0, 100.0, -100.0, 1.0], 0.0)
    d.advance(0.001)
    np.testing.assert_array_equal(d.state()[2], [150.0, -150.0, 10.0, 28.0, -28.0, 1.0])


def test_command_timeout_closes_the_brakes(arm: MujocoArm) -> None:
    d = driver(arm, command_timeout=0.05)
    d.command([0.0, 0.0, 0.0], 0.0)
    assert d.advance(0.04) is False
    assert d.advance(0.06) is True and d.braked
    frozen = d.state()
    np.testing.assert_array_equal(frozen[1], 0.0)
    d.advance(0.5)
    np.testing.assert_array_equal(d.state()[0], frozen[0])
    d.command([0.0, 0.0, 0.0], 0.6)  # the next command releases them again
    d.advance(0.61)
    assert not d.braked and np.any(d.state()[1] != 0.0)


def test_a_stall_is_caught_up_only_so_far(arm: MujocoArm) -> None:
    d = driver(arm)
    d.command([0.0, 0.0, 0.0], 0.0)
    d.advance(1.0)  # the process stood still for a second
    assert d.steps == round(md.MAX_CATCH_UP_S / 1e-3)
    assert d.skipped == pytest.approx(1.0 - md.MAX_CATCH_UP_S)
    assert d.clock == pytest.approx(1.0)


def test_bad_set_ups_are_one_line(arm: MujocoArm) -> None:
    q0 = md.default_positions("serial_3r")
    with pytest.raises(InvalidInputError, match="joints must name each"):
        md.MujocoDriver(arm, q0, command_joints=["joint1", "joint2", "elbow"])
    with pytest.raises(InvalidInputError, match="3 finite angles"):
        md.MujocoDriver(arm, [0.0, 0.0])
    with pytest.raises(InvalidInputError, match="command_timeout"):
        md.MujocoDriver(arm, q0, command_timeout=-1.0)
    five_bar = build_model("parallel_5r")
    with pytest.raises(InvalidInputError, match="passive joints"):
        md.MujocoDriver(five_bar, md.default_positions("parallel_5r"))


def test_start_angles_outside_the_urdf_limits_are_refused(tmp_path: Path) -> None:
    # MuJoCo turns <limit lower upper> into hard stops: a start beyond one would be thrown back
    urdf = tmp_path / "two.urdf"
    link = ('<link name="{0}"><inertial><origin xyz="0.1 0 0"/><mass value="1"/>'
            '<inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial></link>')
    joint = ('<joint name="{0}" type="revolute"><parent link="{1}"/><child link="{2}"/><origin xyz="{3} 0 0"/>'
             '<axis xyz="0 1 0"/><limit effort="5" velocity="2" lower="-1.0" upper="1.0"/></joint>')
    urdf.write_text('<robot name="two"><link name="base"/>' + link.format("l1") + link.format("l2")
                    + joint.format("hinge1", "base", "l1", 0) + joint.format("hinge2", "l1", "l2", 0.2)
                    + "</robot>")
    two = build_model(str(urdf), timestep=1e-3)
    md.MujocoDriver(two, [0.9, -0.9])
    with pytest.raises(InvalidInputError, match=r"joint 'hinge2' at -1.2 rad is outside its limits \[-1, 1\]"):
        md.MujocoDriver(two, [0.0, -1.2])


def test_joint_state_orders() -> None:
    names = ["b_joint", "c_joint", "a_joint"]
    assert md.joint_state_order(names, "urdf") == [0, 1, 2]
    assert md.joint_state_order(names, "reversed") == [2, 1, 0]
    assert md.joint_state_order(names, "alphabetical") == [2, 0, 1]
    with pytest.raises(InvalidInputError, match="joint_state_order"):
        md.joint_state_order(names, "random")
