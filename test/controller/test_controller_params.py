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
    declare_controller_run,  # noqa: E402
)
from pdsmc_ros.errors import ConfigError  # noqa: E402

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
    run = declare_controller_run(node)
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
    run = declare_controller_run(node)
    robot = run.spec.robot_model()
    params = declare_controller_parameters(node, robot)
    np.testing.assert_array_equal(params.torque_limit, np.asarray(robot.effort_limits)[[2, 0, 1]])
    off = node_with(*base, Parameter("enforce_limits", value=False), Parameter("torque_limit", value=[1.0] * 3))
    declare_controller_run(off)
    assert declare_controller_parameters(off, robot).torque_limit is None


def test_an_unknown_joint_is_refused_naming_the_robots_joints(node_with) -> None:  # noqa: ANN001
    node = node_with(Parameter("robot", value="serial_3r"), Parameter("joints", value=["joint1", "joint2", "wrist"]))
    with pytest.raises(ConfigError, match=r"'wrist' is not a joint of the robot; its actuated joints are "
                                          r"\['joint1', 'joint2', 'joint3'\]"):
        declare_controller_run(node)  # before the gains: they are given in joints order


@pytest.mark.timeout(120)
def test_the_node_exits_2_on_an_unknown_joint(ros_env: dict) -> None:
    proc = subprocess.run(["ros2", "run", "pdsmc_ros", "controller", "--ros-args", "-p", "robot:=serial_3r",
                           "-p", "joints:=[joint1, joint2, wrist]"],
                          env=dict(ros_env, ROS_DOMAIN_ID=str(next_domain())), capture_output=True, text=True,
                          timeout=100)
    assert proc.returncode == 2, proc.stderr
    assert "'wrist' is not a joint of the robot" in proc.stderr and "Traceback" not in proc.stderr


def test_the_goal_process_serves_the_nodes_parameters_as_the_node_would(node_with) -> None:  # noqa: ANN001
    """The goal process's stand-in (:class:`~pdsmc_ros.controller.sidecar.parameter_stand_in.ParameterStandIn`)
    declares every parameter of the node as it is (values, unset gains, descriptors), refuses what the
    node refuses with the same reason, and hands accepted gains over (``("gains", gains, given)``)."""
    from pdsmc_ros.control.stability import check_rate
    from pdsmc_ros.controller.parameters import declare_limit_parameters
    from pdsmc_ros.controller.sidecar.goal_process import parameter_table
    from pdsmc_ros.controller.sidecar.parameter_stand_in import ParameterStandIn
    from pdsmc_ros.loop.realtime_params import declare_realtime_parameters

    node = node_with(Parameter("robot", value="serial_3r"), Parameter("type", value="pd"),
                     Parameter("mode", value="realtime"), Parameter("rate", value=1000.0),
                     Parameter("joints", value=REORDERED),  # gains in joints order: joint3, joint1, joint2
                     Parameter("kp", value=[160.0, 800.0, 800.0]), Parameter("kd", value=[8.0, 40.0, 40.0]))
    run = declare_controller_run(node)
    robot = run.spec.robot_model()
    params = declare_controller_parameters(node, robot)
    declare_limit_parameters(node, robot, params, 1.0 / run.spec.rate, False, run.spec.reference().sample([0.0]).q[0])
    declare_realtime_parameters(node, run.mode)
    reference = run.spec.reference()
    GainUpdates(node, run.spec, lambda new: check_rate(new, reference, **run.stability), lambda gains: None,
                joint_map=params.joint_map)  # as the controller node guards its gains
    sent: list[object] = []
    setup = {"parameters": parameter_table(node), "name": "stand_in_of_controller", "namespace": "/",
             "base": "/controller", "spec": run.spec, "stability": run.stability, "joint_map": params.joint_map}
    stand_in = ParameterStandIn(setup, node.context, sent.append)
    try:
        other = stand_in.node
        names = node._parameters.keys()  # noqa: SLF001 - unset gains too
        assert set(names) <= set(other._parameters)  # noqa: SLF001
        for name in names:
            mine, theirs = node._parameters[name].value, other._parameters[name].value  # noqa: SLF001
            assert (list(theirs) if hasattr(theirs, "tolist") else theirs) == \
                (list(mine) if hasattr(mine, "tolist") else mine), name
            assert other.describe_parameter(name) == node.describe_parameter(name), name
        # what the node refuses, refused alike; the same reasons
        for change in (Parameter("rate", value=500.0), Parameter("kp", value=3000.0),
                       Parameter("kp", value=[1e6, 1e6, 1e6]),
                       Parameter("kd", value=[1e308, 1e308, 1e308]), Parameter("use_sim_time", value=True)):
            mine, theirs = node.set_parameters([change])[0], other.set_parameters([change])[0]
            assert not theirs.successful and theirs.reason == mine.reason, (change.name, theirs.reason, mine.reason)
        assert not sent
        # an accepted gain: set there, handed over in robot order with what was given
        result = other.set_parameters([Parameter("kp", value=[150.0, 700.0, 750.0])])[0]
        assert result.successful, result.reason
        [(kind, gains, given)] = sent
        assert kind == "gains" and list(given["kp"]) == [150.0, 700.0, 750.0]
        assert list(gains["kp"]) == [700.0, 750.0, 150.0]  # in URDF order
        assert stand_in.named.get_name() == "stand_in_of_controller"  # its services: the controller's names
    finally:
        stand_in.destroy()
