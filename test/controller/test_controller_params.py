"""The controller's parameters: joints by name, gains and limits in ``joints`` order, the clamp's source."""

from __future__ import annotations

import subprocess

import numpy as np
import pytest
from conftest import next_domain

pytest.importorskip("rclpy")
import rclpy  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402

from pdsmc_ros.controller.parameters import (
    GainUpdates,  # noqa: E402
    declare_controller_parameters,  # noqa: E402
)
from pdsmc_ros.errors import ConfigError  # noqa: E402
from pdsmc_ros.parameters.run import declare_node_run  # noqa: E402

REORDERED = ["joint3", "joint1", "joint2"]


@pytest.fixture
def node_with():  # noqa: ANN201
    """``make(*overrides)``: a controller-like node with those parameter overrides."""
    context = rclpy.Context()
    rclpy.init(context=context, domain_id=next_domain())
    nodes = []

    def make(*overrides: Parameter) -> rclpy.node.Node:
        node = rclpy.create_node("controller", context=context, parameter_overrides=list(overrides),
                                 start_parameter_services=False)
        nodes.append(node)
        return node

    yield make
    for node in nodes:
        node.destroy_node()
    rclpy.try_shutdown(context=context)


def test_gains_and_limits_given_in_joints_order_land_in_robot_order(node_with) -> None:  # noqa: ANN001
    node = node_with(Parameter("robot", value="serial_3r"), Parameter("type", value="pd"),
                     Parameter("rate", value=1000.0), Parameter("sample_rate", value=1000.0),
                     Parameter("joints", value=REORDERED),
                     Parameter("kp", value=[400.0, 2000.0, 1900.0]), Parameter("kd", value=[20.0, 100.0, 90.0]),
                     Parameter("torque_limit", value=[3.0, 1.0, 2.0]))
    run = declare_node_run(node, gains=True)
    robot = run.spec.robot_model()
    params = declare_controller_parameters(node, robot)
    spec = run.spec  # the one resolver put the gains given in joints order in robot order
    np.testing.assert_array_equal(spec.gains["kp"], [2000.0, 1900.0, 400.0])  # joint1, joint2, joint3
    np.testing.assert_array_equal(spec.gains["kd"], [100.0, 90.0, 20.0])
    np.testing.assert_array_equal(params.torque_limit, [3.0, 1.0, 2.0])  # the clamp works in joints order
    # ros2 param set kp in joints order: validated and applied in robot order
    applied = []
    GainUpdates(node, spec, lambda new: None, applied.append, joint_map=params.joint_map)
    result = node.set_parameters([Parameter("kp", value=[300.0, 1800.0, 1700.0])])[0]
    assert result.successful, result.reason
    np.testing.assert_array_equal(applied[-1]["kp"], [1800.0, 1700.0, 300.0])
    refused = node.set_parameters([Parameter("enforce_limits", value=False)])[0]
    assert not refused.successful and "read-only" in refused.reason  # rclpy refuses a read-only parameter


def test_the_clamp_defaults_to_the_arms_effort_limits_and_opts_out(node_with) -> None:  # noqa: ANN001
    base = [Parameter("robot", value="serial_3r"), Parameter("type", value="pd")]
    node = node_with(*base, Parameter("joints", value=REORDERED))
    run = declare_node_run(node, gains=True)
    robot = run.spec.robot_model()
    params = declare_controller_parameters(node, robot)
    np.testing.assert_array_equal(params.torque_limit, np.asarray(robot.effort_limits)[[2, 0, 1]])
    off = node_with(*base, Parameter("enforce_limits", value=False), Parameter("torque_limit", value=[1.0] * 3))
    declare_node_run(off, gains=True)
    assert declare_controller_parameters(off, robot).torque_limit is None


def test_an_unknown_joint_is_refused_naming_the_robots_joints(node_with) -> None:  # noqa: ANN001
    node = node_with(Parameter("robot", value="serial_3r"), Parameter("joints", value=["joint1", "joint2", "wrist"]))
    with pytest.raises(ConfigError, match=r"'wrist' is not a joint of the robot; its actuated joints are "
                                          r"\['joint1', 'joint2', 'joint3'\]"):
        declare_node_run(node, gains=True)  # before the gains: they are given in joints order


@pytest.mark.timeout(120)
def test_the_node_exits_2_on_an_unknown_joint(ros_env: dict) -> None:
    proc = subprocess.run(["ros2", "run", "pdsmc_ros", "controller", "--ros-args", "-p", "robot:=serial_3r",
                           "-p", "joints:=[joint1, joint2, wrist]"],
                          env=dict(ros_env, ROS_DOMAIN_ID=str(next_domain())), capture_output=True, text=True,
                          timeout=100)
    assert proc.returncode == 2, proc.stderr
    assert "'wrist' is not a joint of the robot" in proc.stderr and "Traceback" not in proc.stderr
