"""The plant's own parameters (besides the run's), validated at start.

``expected_subscribers`` (the readers of ``/joint_states`` a lockstep run waits for),
``enforce_limits`` (the applied torque clamped to the arm's effort limits) and the safety
parameters (:data:`~.descriptors.SAFETY_PARAMETERS`: the watchdog, safe mode and its gains).
"""

from __future__ import annotations

from dataclasses import dataclass

from rcl_interfaces.msg import ParameterDescriptor
from rclpy.node import Node

from ..control.safety import SafetyConfig, Watchdog
from ..errors import ConfigError
from .descriptors import declare_int_parameter, declare_safety_parameters, safety_from_parameters


@dataclass(frozen=True)
class PlantParameters:
    """The plant's own parameters, validated."""

    expected_subscribers: int
    enforce_limits: bool
    watchdog: Watchdog  # effort commands missing for too long: safe mode
    safety: SafetyConfig


def declare_plant_parameters(node: Node, rate: float) -> PlantParameters:
    """Declare the plant's parameters (a ``rate`` Hz run) and return them validated; a
    ConfigError naming the parameter if bad."""
    expected = declare_int_parameter(
        node, "expected_subscribers", 3,
        "subscribers of /joint_states to wait for (trajectory, controller, recorder)", lo=0, hi=100)
    declare_safety_parameters(node)
    if not node.has_parameter("enforce_limits"):
        node.declare_parameter("enforce_limits", True, ParameterDescriptor(
            description="clamp the applied torque to the arm's effort limits (false: opt out)"))
    enforce = node.get_parameter("enforce_limits").value
    if not isinstance(enforce, bool):
        raise ConfigError(f"parameter enforce_limits must be true or false, got {enforce!r}")
    safety = safety_from_parameters(node)
    watchdog = Watchdog(rate=rate, timeout_s=float(node.get_parameter("watchdog_timeout").value),
                        periods=int(node.get_parameter("watchdog_periods").value),
                        time_scale=float(node.get_parameter("safe_time_scale").value))
    return PlantParameters(expected, enforce, watchdog, safety)
