"""Parameter descriptors and declarations the nodes share (validated on set: ranges, types),
the safety parameters, and numbers derived from them."""

from __future__ import annotations

from typing import Any

from rcl_interfaces.msg import FloatingPointRange, ParameterDescriptor
from rclpy.node import Node

from ..checks import is_real, is_whole
from ..control.safety import MAX_SAFE_DAMPING, MAX_SAFE_STIFFNESS, SafetyConfig
from ..errors import ConfigError, InvalidInputError
from ..runtime.realtime import AUTO_BUSY_WAIT


def descriptor(
    description: str, *, lo: float | None = None, hi: float | None = None, constraints: str = ""
) -> ParameterDescriptor:
    # dynamic typing: `-p rate:=1000` (an integer) is accepted and checked by us,
    # so a wrong type is one clear line instead of an rclpy traceback
    desc = ParameterDescriptor(
        description=description, additional_constraints=constraints, dynamic_typing=True
    )
    if lo is not None and hi is not None:
        desc.floating_point_range = [FloatingPointRange(from_value=lo, to_value=hi, step=0.0)]
    return desc


SAFETY_PARAMETERS: dict[str, tuple[Any, ParameterDescriptor]] = {
    "watchdog_timeout": (2.0, descriptor(
        "lockstep: wall-clock seconds without effort before safe mode (checked every 20 ms)", lo=0.05, hi=3600.0)),
    "watchdog_periods": (20, descriptor("real time: control periods without effort before safe mode")),
    "safe_mode": ("damp", descriptor("safe mode", constraints="damp (braking only) or hold (hold position)")),
    "safe_damping": (5.0, descriptor("safe-mode braking gain in N m s/rad", lo=0.0, hi=MAX_SAFE_DAMPING)),
    "safe_stiffness": (200.0, descriptor("hold-mode stiffness in N m/rad", lo=0.0, hi=MAX_SAFE_STIFFNESS)),
    "on_controller_loss": ("resume", descriptor("after safe mode", constraints="resume or end")),
    "safe_time_scale": (1.0, descriptor(
        "lockstep: sim seconds the plant advances per wall second in safe mode (1: real time, 0: frozen)",
        lo=0.0, hi=1000.0)),
}


def declare_safety_parameters(node: Node) -> None:
    for name, (default, desc) in SAFETY_PARAMETERS.items():
        node.declare_parameter(name, default, desc)


def safety_from_parameters(node: Node) -> SafetyConfig:
    """The plant's SafetyConfig, validated (ConfigError naming the parameter)."""
    values = {name: node.get_parameter(name).value for name in SAFETY_PARAMETERS}
    for name in ("watchdog_timeout", "safe_damping", "safe_stiffness", "safe_time_scale"):
        if not is_real(values[name]):
            raise ConfigError(f"parameter {name} must be a number, got {values[name]!r}")
    if not 0.0 <= values["safe_time_scale"] <= 1000.0:
        raise ConfigError(f"parameter safe_time_scale must be in [0, 1000], got {values['safe_time_scale']!r}")
    if not is_whole(values["watchdog_periods"]) or values["watchdog_periods"] < 1:
        raise ConfigError(f"parameter watchdog_periods must be a whole number >= 1, got {values['watchdog_periods']!r}")
    try:
        return SafetyConfig(mode=values["safe_mode"], damping=float(values["safe_damping"]),
                            stiffness=float(values["safe_stiffness"]), on_loss=values["on_controller_loss"])
    except InvalidInputError as exc:
        raise ConfigError(f"parameter {exc}") from None


def declare_int_parameter(node: Node, name: str, default: int, description: str, *,
                          lo: int, hi: int) -> int:
    """Declare a whole-number parameter and return its value, checked against [lo, hi].

    A wrong type or range is a ConfigError naming the parameter and what is allowed.
    """
    node.declare_parameter(name, default, ParameterDescriptor(
        description=description, additional_constraints=f"a whole number in [{lo}, {hi}]",
        dynamic_typing=True))
    value = node.get_parameter(name).value
    if not is_whole(value) or not lo <= value <= hi:
        raise ConfigError(f"parameter {name} must be a whole number in [{lo}, {hi}], got {value!r}")
    return value


def declare_busy_wait(node: Node) -> float:
    """Declare ``busy_wait`` and return it: real time, seconds before each tick spent
    busy-waiting instead of sleeping, or ``AUTO_BUSY_WAIT`` (-1, the default: chosen from the
    scheduling by :func:`~pdsmc_ros.runtime.realtime.busy_wait_for`); a ConfigError if bad."""
    node.declare_parameter("busy_wait", AUTO_BUSY_WAIT, descriptor(
        "real time: seconds before each tick spent busy-waiting instead of sleeping (absorbs late "
        "wake-ups, costs that share of a core); -1 (default): 0.0002 at normal priority, at SCHED_FIFO "
        "0.00005, 0.0003 for a process ticking several loop nodes; at SCHED_FIFO at most half a period",
        lo=AUTO_BUSY_WAIT, hi=1.0))
    value = node.get_parameter("busy_wait").value
    if not is_real(value) or not (value == AUTO_BUSY_WAIT or 0.0 <= value <= 1.0):
        raise ConfigError(f"parameter busy_wait must be -1 (automatic) or a number of seconds in [0, 1], got {value!r}")
    return float(value)


def decimation(rate: float, target: float) -> int:
    """Publish every ``decimation`` steps so a ``rate`` Hz loop emits at most ``target`` Hz."""
    return max(1, int(round(rate / target)))
