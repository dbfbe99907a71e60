"""The plant's own parameters (besides the run's), declared from its table and validated at start.

``expected_subscribers`` (the readers of ``/joint_states`` a lockstep run waits for),
``enforce_limits`` (the applied torque clamped to the arm's effort limits) and the safety
parameters (:data:`~pdsmc_ros.parameters.SAFETY`: the watchdog, safe mode and its gains).
"""

from __future__ import annotations

from dataclasses import dataclass

from rclpy.node import Node

from ..errors import ConfigError, InvalidInputError
from ..parameters import PLANT, SAFETY
from ..parameters.ros import declare
from ..sim.safe_mode import SafetyConfig, Watchdog


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
    values = declare(node, (*PLANT, *SAFETY))
    try:
        safety = SafetyConfig(mode=values["safe_mode"], damping=values["safe_damping"],
                              stiffness=values["safe_stiffness"], on_loss=values["on_controller_loss"])
    except InvalidInputError as exc:
        raise ConfigError(f"parameter {exc}") from None
    watchdog = Watchdog(rate=rate, timeout_s=values["watchdog_timeout"], periods=values["watchdog_periods"],
                        time_scale=values["safe_time_scale"])
    return PlantParameters(values["expected_subscribers"], values["enforce_limits"], watchdog, safety)
