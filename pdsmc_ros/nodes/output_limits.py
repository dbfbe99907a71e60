"""The controller's output limits as parameters: the arm's soft limits and the runaway guard.

``soft_limits.k_position`` and ``soft_limits.k_velocity`` are ros2_control's soft-limit gains
(:func:`pdsmc_ros.control.safety.soft_limit`); ``runaway.velocity_factor``,
``runaway.position_margin`` and ``runaway.stop`` set the runaway guard
(:class:`pdsmc_ros.runtime.commanding.RunawayGuard`). All are read at start (read-only), and
none applies with ``enforce_limits:=false``.
"""

from __future__ import annotations

import numpy as np
from rclpy.node import Node

from ..control.safety import effort_only_table, robot_soft_limits
from ..errors import ConfigError, InvalidInputError
from ..parameters import OUTPUT_LIMITS
from ..parameters.ros import declare
from ..robots.base import FloatArray, Manipulator
from ..runtime.commanding import RunawayGuard
from .controller_params import ControllerParameters


def declare_limit_parameters(node: Node, robot: Manipulator, params: ControllerParameters, period: float,
                             lockstep: bool, start_q: FloatArray) -> tuple[FloatArray | None, RunawayGuard | None]:
    """Declare the output-limit parameters; the output-limit table (robot order) and the runaway
    guard, each None with ``enforce_limits:=false``.

    Real time: the soft limits about the run's start configuration ``start_q``
    (:func:`~pdsmc_ros.control.safety.robot_soft_limits`) and the runaway guard. Lockstep: the
    effort clamp alone, as the in-process simulator runs (a lockstep run is a simulation whose
    divergence test must see an unstable law run away: soft limits would hold it at the velocity
    limit), and no runaway guard.

    Raises
    ------
    ConfigError
        A value out of range or of the wrong type, naming the parameter.
    """
    values = declare(node, OUTPUT_LIMITS)  # read-only; each of its type and in its bounds
    k_position, k_velocity = values["soft_limits.k_position"], values["soft_limits.k_velocity"]
    factor, margin, stop = values["runaway.velocity_factor"], values["runaway.position_margin"], values["runaway.stop"]
    if k_velocity is not None and len(k_velocity) != robot.n:
        raise ConfigError(f"parameter soft_limits.k_velocity must be {robot.n} numbers >= 0 (N m s/rad, joints order) "
                          f"or empty, got {k_velocity!r}")
    if not params.enforce_limits:
        return None, None
    joint_map = params.joint_map
    effort = (np.asarray(robot.effort_limits, dtype=float) if params.torque_limit is None
              else joint_map.to_robot(params.torque_limit))
    if lockstep:
        return effort_only_table(effort, robot.n), None
    gains = None if not k_velocity else joint_map.to_robot([float(v) for v in k_velocity])
    try:
        table = robot_soft_limits(robot, start_q, 1.0 / period, k_position=float(k_position),
                                  k_velocity=gains, effort=effort)
    except InvalidInputError as exc:
        raise ConfigError(f"parameter {exc}") from None
    runaway = RunawayGuard(robot.joint_names, robot.position_limits, robot.velocity_limits, effort,
                           inertia=lambda q: np.diag(robot.mass_matrix(q)), period=period,
                           velocity_factor=float(factor), position_margin=float(margin),
                           stop=str(stop))
    return table, runaway
