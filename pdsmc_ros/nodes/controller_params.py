"""The controller's own parameters (besides the run's and the gains), validated at start.

``joints`` (by name, any order: the order of the command's ``data``, of gains and
torque limits given as parameters and of every per-joint output), ``autostart``,
``torque_limit``, ``enforce_limits``, ``stale_periods``, the action's default
tolerances (``constraints.goal_time``, ``constraints.stopped_velocity_tolerance``,
``constraints.<joint>.trajectory`` and ``.goal``) and how trajectories are taken (``cmd_timeout``,
``allow_partial_joints_goal``, ``allow_nonzero_velocity_at_trajectory_end``, ``allowed_start_tolerance``,
``reject_beyond_limits``), as joint_trajectory_controller names them: declared once in
:data:`~pdsmc_ros.parameters.CONTROLLER` (read-only: a running controller does not re-read them).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from rclpy.node import Node

from ..errors import ConfigError
from ..parameters import CONTROLLER
from ..parameters.ros import declare
from ..robots import Manipulator
from ..runtime.goal import GoalSettings, Tolerances
from ..runtime.joint_map import JointMap
from ..runtime.joint_trajectory import TrajectoryRules


@dataclass(frozen=True)
class ControllerParameters:
    """The controller's own parameters, validated; vectors in ``joints`` order."""

    joint_map: JointMap
    autostart: bool
    torque_limit: np.ndarray | None  # the clamp (joints order): torque_limit, else the arm's; None: opt-out
    enforce_limits: bool
    stale_periods: int
    goal_settings: GoalSettings  # trajectories and goals: JTC's parameters, the default tolerances (robot order)
    action_introspection: str  # accepted goals as SendGoal service events: disabled, metadata or contents

    @property
    def joints(self) -> tuple[str, ...]:
        return self.joint_map.joints


def declare_controller_parameters(node: Node, robot: Manipulator) -> ControllerParameters:
    """Declare the controller's parameters (if :func:`~.params.declare_node_run` has not) and return
    them validated; a ConfigError naming the parameter if bad (an unknown joint name lists the robot's)."""
    values = declare(node, CONTROLLER, defaults={"joints": list(robot.joint_names)})
    joint_map = JointMap(robot.joint_names, values["joints"])
    limit = values["torque_limit"]
    if limit is not None and len(limit) != robot.n:
        raise ConfigError(f"parameter torque_limit needs {robot.n} values > 0 (N m), one per joint, got {limit}")
    limit = None if limit is None else np.asarray(limit, dtype=float)
    if not values["enforce_limits"]:
        if limit is not None:
            node.get_logger().warn("enforce_limits is false: torque_limit is not applied")
        limit = None
    elif limit is None:
        effort = getattr(robot, "effort_limits", None)
        limit = None if effort is None else joint_map.to_user(np.asarray(effort, dtype=float))
    per_joint = {kind: joint_map.to_robot([values[f"constraints.{joint}.{kind}"] for joint in joint_map.joints])
                 for kind in ("trajectory", "goal")}
    defaults = Tolerances.defaults(robot.n, stopped_velocity=values["constraints.stopped_velocity_tolerance"],
                                   goal_time=values["constraints.goal_time"], trajectory=per_joint["trajectory"],
                                   goal=per_joint["goal"])
    rules = TrajectoryRules(values["allow_partial_joints_goal"], values["allow_nonzero_velocity_at_trajectory_end"])
    try:
        settings = GoalSettings(rules, defaults, values["cmd_timeout"], values["allowed_start_tolerance"],
                                values["reject_beyond_limits"])
    except ValueError as exc:
        raise ConfigError(f"parameter {exc}") from None
    return ControllerParameters(joint_map, values["autostart"], limit, values["enforce_limits"],
                                values["stale_periods"], settings, values["action_introspection"])
