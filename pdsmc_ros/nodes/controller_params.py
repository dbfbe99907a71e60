"""The controller's own parameters (besides the run's and the gains), validated at start.

``joints`` (by name, any order: the order of the command's ``data``, of gains and
torque limits given as parameters and of every per-joint output), ``autostart``,
``torque_limit``, ``enforce_limits``, ``stale_periods`` and the action's default
tolerances (``constraints.goal_time``, ``constraints.stopped_velocity_tolerance``,
as joint_trajectory_controller names them).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
from rcl_interfaces.msg import ParameterDescriptor, SetParametersResult
from rclpy.exceptions import ParameterUninitializedException
from rclpy.node import Node
from rclpy.parameter import Parameter

from ..checks import are_real, is_real
from ..control import GAINS, Gains
from ..errors import ConfigError
from ..presets import RunSpec, scenario_gain_factors
from ..robots import Manipulator
from ..runtime.goal import STOPPED_VELOCITY_TOLERANCE, GoalSettings, Tolerances
from ..runtime.joint_map import JointMap
from ..runtime.joint_trajectory import TrajectoryRules
from ..runtime.limits import START_TOLERANCE
from .descriptors import declare_int_parameter
from .gain_updates import GainUpdates

FIXED = ("torque_limit", "enforce_limits", "stale_periods", "constraints.goal_time",
         "constraints.stopped_velocity_tolerance", "allow_partial_joints_goal",
         "allow_nonzero_velocity_at_trajectory_end", "cmd_timeout", "reject_beyond_limits",
         "allowed_start_tolerance")
"""The controller's own parameters that a running controller does not re-read."""


def torque_limit_from_parameters(node: Node, n: int) -> np.ndarray | None:
    """``torque_limit`` (one positive number per joint, or unset), validated."""
    value = node.get_parameter("torque_limit").value
    if value is None or (not isinstance(value, str) and len(value) == 0):
        return None
    if not are_real(value):
        raise ConfigError(f"parameter torque_limit must be a list of {n} numbers, got {value!r}")
    limit = np.asarray(value, dtype=float)
    if limit.shape != (n,) or not np.all(np.isfinite(limit)) or np.any(limit <= 0):
        raise ConfigError(f"parameter torque_limit needs {n} finite values > 0 (N m), got {list(value)}")
    return limit


@dataclass(frozen=True)
class ControllerParameters:
    """The controller's own parameters, validated; vectors in ``joints`` order."""

    joint_map: JointMap
    autostart: bool
    torque_limit: np.ndarray | None  # the clamp (joints order): torque_limit, else the arm's; None: opt-out
    enforce_limits: bool
    stale_periods: int
    goal_settings: GoalSettings  # trajectories and goals: JTC's parameters, the default tolerances (robot order)

    @property
    def joints(self) -> tuple[str, ...]:
        return self.joint_map.joints


def _number(node: Node, name: str, default: float, description: str) -> float:
    node.declare_parameter(name, default, ParameterDescriptor(description=description, dynamic_typing=True))
    value = node.get_parameter(name).value
    if not is_real(value) or not value >= 0.0:
        raise ConfigError(f"parameter {name} must be a number >= 0, got {value!r}")
    return float(value)


def declare_controller_parameters(node: Node, robot: Manipulator) -> ControllerParameters:
    """Declare the controller's parameters and return them validated; a ConfigError naming
    the parameter if bad (an unknown joint name lists the robot's)."""
    node.declare_parameter("joints", list(robot.joint_names), ParameterDescriptor(
        description="the controlled joints by name, any order (default: the robot's actuated joints in "
                    "URDF order); the order of the command's data, of gains and torque_limit given as "
                    "parameters and of every per-joint output", dynamic_typing=True))
    node.declare_parameter("autostart", True, ParameterDescriptor(
        description="configure and activate at start (false: wait for the lifecycle transitions)"))
    node.declare_parameter("torque_limit", None, ParameterDescriptor(
        description="per-joint torque limits in N m, joints order (default: the arm's effort limits)",
        dynamic_typing=True))
    node.declare_parameter("enforce_limits", True, ParameterDescriptor(
        description="clamp torques to the limits and refuse trajectories outside the joint limits "
                    "(false: opt out of both)"))
    stale_periods = declare_int_parameter(
        node, "stale_periods", 20, "real time: periods after which a state or reference is stale", lo=1, hi=10**6)
    goal_time = _number(node, "constraints.goal_time", 0.0,
                        "action goals: default goal_time_tolerance in s (0: wait for the goal tolerances)")
    stopped = _number(node, "constraints.stopped_velocity_tolerance", STOPPED_VELOCITY_TOLERANCE,
                      "action goals: default goal velocity tolerance in rad/s (0: not checked)")
    cmd_timeout = _number(node, "cmd_timeout", 0.0, "hold the measured position this long (s) after a trajectory's "
                          "last point (0: never; ignored unless above constraints.goal_time)")
    start_tolerance = _number(node, "allowed_start_tolerance", START_TOLERANCE, "beyond JTC: a trajectory whose "
                              "reference at receipt is more than this (rad) from the current position is a step")
    for name, default, description in (
            ("allow_partial_joints_goal", False, "accept trajectories naming some of the joints (the others hold)"),
            ("allow_nonzero_velocity_at_trajectory_end", False, "accept trajectories whose last point moves"),
            ("reject_beyond_limits", True, "beyond JTC: reject trajectories beyond the arm's limits or with a step")):
        node.declare_parameter(name, default, ParameterDescriptor(description=description))
    autostart, enforce = node.get_parameter("autostart").value, node.get_parameter("enforce_limits").value
    flags = {name: node.get_parameter(name).value for name in (
        "allow_partial_joints_goal", "allow_nonzero_velocity_at_trajectory_end", "reject_beyond_limits")}
    for name, value in (("autostart", autostart), ("enforce_limits", enforce), *flags.items()):
        if not isinstance(value, bool):
            raise ConfigError(f"parameter {name} must be true or false, got {value!r}")
    joint_map = JointMap(robot.joint_names, node.get_parameter("joints").value)
    per_joint = {kind: joint_map.to_robot([
        _number(node, f"constraints.{joint}.{kind}", 0.0, f"default {kind} position tolerance of {joint} in rad")
        for joint in joint_map.joints]) for kind in ("trajectory", "goal")}
    limit = torque_limit_from_parameters(node, robot.n)
    if not enforce:
        if limit is not None:
            node.get_logger().warn("enforce_limits is false: torque_limit is not applied")
        limit = None
    elif limit is None:
        effort = getattr(robot, "effort_limits", None)
        limit = None if effort is None else joint_map.to_user(np.asarray(effort, dtype=float))
    defaults = Tolerances.defaults(robot.n, stopped_velocity=stopped, goal_time=goal_time,
                                   trajectory=per_joint["trajectory"], goal=per_joint["goal"])
    rules = TrajectoryRules(flags["allow_partial_joints_goal"], flags["allow_nonzero_velocity_at_trajectory_end"])
    try:
        settings = GoalSettings(rules, defaults, cmd_timeout, start_tolerance, flags["reject_beyond_limits"])
    except ValueError as exc:
        raise ConfigError(f"parameter {exc}") from None
    return ControllerParameters(joint_map, autostart, limit, enforce, stale_periods, settings)


def gains_in_robot_order(node: Node, spec: RunSpec, joint_map: JointMap) -> RunSpec:
    """The run with the gains given as parameters (in ``joints`` order) put in robot order."""
    if joint_map.identity:
        return spec
    rows = spec.gains.as_dict()
    factors = scenario_gain_factors(spec.scenario, spec.controller)  # as given gains are scaled in robot order
    for name in GAINS:
        try:
            value = node.get_parameter(name).value if node.has_parameter(name) else None
        except ParameterUninitializedException:
            continue  # not given: the preset's row, already in robot order
        if value is not None and len(value) == len(joint_map.joints):
            rows[name] = (joint_map.to_robot([float(v) for v in value]) * factors.get(name, 1.0)).tolist()
    return dataclasses.replace(spec, gains=Gains.from_mapping(rows, len(joint_map.joints), spec.controller))


class OrderedGainUpdates(GainUpdates):
    """:class:`GainUpdates` for gains set in ``joints`` order (``ros2 param set``): put in robot order first."""

    joint_map: JointMap

    def validate(self, params: list[Parameter]) -> SetParametersResult:
        for param in params:
            if param.name in FIXED:
                return SetParametersResult(successful=False,
                                           reason=f"{param.name} is read at start and cannot change while it runs")
        ordered = [Parameter(p.name, value=self.joint_map.to_robot(p.value).tolist())
                   if p.name in GAINS and p.value is not None and len(p.value) == len(self.joint_map.joints)
                   else p for p in params]
        return super().validate(ordered)
