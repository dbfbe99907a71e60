"""The controller's output limits as parameters: the arm's soft limits and the runaway guard.

``soft_limits.k_position`` and ``soft_limits.k_velocity`` are ros2_control's soft-limit gains
(:func:`pdsmc_ros.control.safety.soft_limit`); ``runaway.velocity_factor``,
``runaway.position_margin`` and ``runaway.stop`` set the runaway guard
(:class:`pdsmc_ros.runtime.commanding.RunawayGuard`). All are read at start (read-only), and
none applies with ``enforce_limits:=false``.
"""

from __future__ import annotations

import numpy as np
from rcl_interfaces.msg import ParameterDescriptor
from rclpy.node import Node

from ..checks import are_real, is_real
from ..control.safety import DEFAULT_K_POSITION, SOFT_VELOCITY_BAND, robot_soft_limits
from ..errors import ConfigError, InvalidInputError
from ..robots.base import FloatArray, Manipulator
from ..runtime.commanding import (
    DEFAULT_RUNAWAY_POSITION_MARGIN,
    DEFAULT_RUNAWAY_VELOCITY_FACTOR,
    RUNAWAY_STOPS,
    RunawayGuard,
)
from .controller_params import ControllerParameters


def _declare(node: Node, name: str, default: object, description: str) -> object:
    node.declare_parameter(name, default, ParameterDescriptor(description=description, read_only=True,
                                                              dynamic_typing=True))
    return node.get_parameter(name).value


def declare_limit_parameters(node: Node, robot: Manipulator, params: ControllerParameters, period: float,
                             lockstep: bool, start_q: FloatArray) -> tuple[FloatArray | None, RunawayGuard | None]:
    """Declare the output-limit parameters; the soft-limit table (robot order, about the run's
    start configuration ``start_q``: :func:`~pdsmc_ros.control.safety.robot_soft_limits`) and the runaway
    guard (real time only: a lockstep run's divergence test ends a run that runs away), each
    None with ``enforce_limits:=false``.

    Raises
    ------
    ConfigError
        A value out of range or of the wrong type, naming the parameter.
    """
    k_position = _declare(node, "soft_limits.k_position", DEFAULT_K_POSITION,
                          "soft limits: allowed velocity toward a position limit per rad of distance to it (1/s, "
                          ">= 0; ros2_control's k_position)")
    k_velocity = _declare(node, "soft_limits.k_velocity", None,
                          "soft limits: per joint, joints order, the effort bound's slope beyond the velocity bound "
                          "(N m s/rad, >= 0; ros2_control's k_velocity); default effort limit / "
                          f"({SOFT_VELOCITY_BAND:g} x velocity limit): the whole effort up to 90 % of the velocity "
                          "limit")
    factor = _declare(node, "runaway.velocity_factor", DEFAULT_RUNAWAY_VELOCITY_FACTOR,
                      "real time: a joint faster than this many times its velocity limit stops the motion (> 0)")
    margin = _declare(node, "runaway.position_margin", DEFAULT_RUNAWAY_POSITION_MARGIN,
                      "real time: a joint this far beyond a position limit stops the motion (rad, >= 0)")
    stop = _declare(node, "runaway.stop", "damp",
                    "real time: the output once the runaway guard tripped: damp (a damping torque that brings the "
                    "arm to rest) or zero (no torque)")
    if not is_real(k_position) or not 0.0 <= float(k_position) < np.inf:  # type: ignore[arg-type]
        raise ConfigError(f"parameter soft_limits.k_position must be a finite number >= 0 (1/s), got {k_position!r}")
    n = robot.n
    if k_velocity is not None and (not are_real(k_velocity) or len(k_velocity) not in (0, n)):  # type: ignore[arg-type]
        raise ConfigError(f"parameter soft_limits.k_velocity must be {n} numbers >= 0 (N m s/rad, joints order) or "
                          f"empty, got {k_velocity!r}")
    if not is_real(factor) or not 0.0 < float(factor) < np.inf:  # type: ignore[arg-type]
        raise ConfigError(f"parameter runaway.velocity_factor must be a finite number > 0, got {factor!r}")
    if not is_real(margin) or not 0.0 <= float(margin) < np.inf:  # type: ignore[arg-type]
        raise ConfigError(f"parameter runaway.position_margin must be a finite number >= 0 (rad), got {margin!r}")
    if stop not in RUNAWAY_STOPS:
        raise ConfigError(f"parameter runaway.stop must be one of {', '.join(RUNAWAY_STOPS)}, got {stop!r}")
    if not params.enforce_limits:
        return None, None
    joint_map = params.joint_map
    effort = (np.asarray(robot.effort_limits, dtype=float) if params.torque_limit is None
              else joint_map.to_robot(params.torque_limit))
    gains = None if not k_velocity else joint_map.to_robot([float(v) for v in k_velocity])  # type: ignore[union-attr]
    try:
        table = robot_soft_limits(robot, start_q, 1.0 / period, k_position=float(k_position),  # type: ignore[arg-type]
                                  k_velocity=gains, effort=effort)
    except InvalidInputError as exc:
        raise ConfigError(f"parameter {exc}") from None
    if lockstep:
        return table, None
    runaway = RunawayGuard(robot.joint_names, robot.position_limits, robot.velocity_limits, effort,
                           inertia=lambda q: np.diag(robot.mass_matrix(q)), period=period,
                           velocity_factor=float(factor), position_margin=float(margin),  # type: ignore[arg-type]
                           stop=str(stop))
    return table, runaway
