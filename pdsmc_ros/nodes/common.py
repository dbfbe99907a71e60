"""Shared plumbing of the pdsmc_ros nodes: run parameters, QoS, topics, lifecycle.

Nothing here computes physics, control or metrics; it only turns ROS
parameters into a :class:`~pdsmc_ros.presets.RunSpec` and wires messages.
"""

from __future__ import annotations

import json
import os
import signal
import sys
import threading
from collections.abc import Callable, Sequence
from typing import Any

import rclpy
from rcl_interfaces.msg import FloatingPointRange, ParameterDescriptor, SetParametersResult
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from ..errors import ConfigError, InvalidInputError, PdsmcError
from ..presets import (
    CONTROLLER_NAMES,
    GAIN_NAMES,
    ROBOT_NAMES,
    Gains,
    RunSpec,
    make_run,
)

# --------------------------------------------------------------------------- #
# Topics (ros2_control conventions where they exist)
# --------------------------------------------------------------------------- #
TOPIC_JOINT_STATES = "joint_states"
TOPIC_EFFORT = "effort_controller/commands"
TOPIC_REFERENCE = "reference"
TOPIC_EE_DESIRED = "end_effector/desired"
TOPIC_EE_ACTUAL = "end_effector/actual"
TOPIC_DESCRIPTION = "pdsmc/run_description"
TOPIC_TIMING = "pdsmc/controller_timing"
TOPIC_DIAGNOSTICS = "diagnostics"

MODES = ("lockstep", "realtime")

# Every sample must arrive, in order: reliable, keep-all (NOTES: KEEP_LAST lost data).
LOCKSTEP_QOS = QoSProfile(
    reliability=ReliabilityPolicy.RELIABLE,
    history=HistoryPolicy.KEEP_ALL,
    durability=DurabilityPolicy.VOLATILE,
)
# The run description is published once and must reach late joiners.
LATCHED_QOS = QoSProfile(
    reliability=ReliabilityPolicy.RELIABLE,
    history=HistoryPolicy.KEEP_LAST,
    depth=1,
    durability=DurabilityPolicy.TRANSIENT_LOCAL,
)

EXIT_OK = 0
EXIT_FAILURE = 1
EXIT_BAD_INPUT = 2


def _descriptor(
    description: str, *, lo: float | None = None, hi: float | None = None, constraints: str = ""
) -> ParameterDescriptor:
    desc = ParameterDescriptor(description=description, additional_constraints=constraints)
    if lo is not None and hi is not None:
        desc.floating_point_range = [FloatingPointRange(from_value=lo, to_value=hi, step=0.0)]
    return desc


RUN_PARAMETERS: dict[str, tuple[Any, ParameterDescriptor]] = {
    "robot": ("serial_3r", _descriptor("manipulator", constraints="one of: " + ", ".join(ROBOT_NAMES))),
    "contour": ("circle", _descriptor("contour preset (config/contours.yaml) or csv")),
    "type": ("pdsmc", _descriptor("controller type", constraints="one of: " + ", ".join(CONTROLLER_NAMES))),
    "scenario": ("nominal", _descriptor("robustness scenario (config/scenarios.yaml)")),
    "mode": ("lockstep", _descriptor("timing mode", constraints="one of: lockstep, realtime")),
    "rate": (0.0, _descriptor("control rate in Hz (0: preset, 10 kHz serial / 5 kHz parallel)", lo=0.0, hi=1.0e6)),
    "sample_rate": (0.0, _descriptor("statistics rate in Hz (0: thesis value)", lo=0.0, hi=1.0e6)),
    "duration_factor": (1.0, _descriptor("multiplies the contour duration", lo=0.001, hi=1000.0)),
    "smc_reading": ("literal", _descriptor("SMC model estimate (config/smc_readings.yaml)")),
    "ellipse_error": ("nearest", _descriptor("ellipse contour error", constraints="nearest or osculating")),
    "waypoints_file": ("", _descriptor("CSV of task-space waypoints for contour csv")),
    "segment_duration": (2.0, _descriptor("seconds per CSV segment", lo=0.001, hi=1000.0)),
}
GAIN_DESCRIPTIONS = {
    "kp": "proportional gains Kp, one per joint (empty: preset of Table 4.16 / 4.33)",
    "kd": "derivative gains Kd, one per joint (empty: preset)",
    "ks": "switching gains Ks, one per joint (empty: preset)",
    "lam": "sliding-surface slopes lambda, one per joint (empty: preset)",
    "phi": "boundary layers phi > 0, one per joint (empty: preset)",
}


def declare_run_parameters(node: Node, *, gains: bool = False) -> None:
    """Declare the parameters that define a run (and the gains, for the controller)."""
    for name, (default, desc) in RUN_PARAMETERS.items():
        node.declare_parameter(name, default, desc)
    if gains:
        for name in GAIN_NAMES:
            node.declare_parameter(
                name, Parameter.Type.DOUBLE_ARRAY, _descriptor(GAIN_DESCRIPTIONS[name])
            )


def run_spec_from_parameters(node: Node) -> RunSpec:
    """Build and validate the RunSpec named by the node's parameters.

    Raises
    ------
    InvalidInputError
        With a message naming the parameter and what is allowed.
    """
    p = {name: node.get_parameter(name).value for name in RUN_PARAMETERS}
    if p["mode"] not in MODES:
        raise ConfigError(f"parameter mode: unknown value {p['mode']!r}; choose one of: lockstep, realtime")
    from ..reproduce import smc_reading

    try:
        spec = make_run(
            p["robot"],
            p["contour"],
            p["type"],
            scenario=p["scenario"],
            rate=p["rate"] or None,
            sample_rate=p["sample_rate"] or None,
            smc_model=smc_reading(p["smc_reading"]) if p["type"] == "smc" else None,
            ellipse_error=p["ellipse_error"],
            waypoints_file=p["waypoints_file"] or None,
            segment_duration=p["segment_duration"],
        )
    except ConfigError as exc:
        raise ConfigError(f"parameters: {exc}") from None
    if p["duration_factor"] != 1.0:
        import dataclasses

        spec = dataclasses.replace(spec, duration_factor=spec.duration_factor * p["duration_factor"])
    overrides = {}
    for name in GAIN_NAMES:
        if node.has_parameter(name):
            value = node.get_parameter(name).value
            if value is not None and len(value) > 0:
                overrides[name] = list(value)
    if overrides:
        import dataclasses

        merged = {**spec.gains.as_dict(), **overrides}
        n = len(spec.gains.kp)
        gains = Gains.from_mapping(merged, n, spec.controller)
        spec = dataclasses.replace(spec, gains=gains)
    return spec


def gains_callback(node: Node, spec_holder: dict[str, RunSpec]) -> Callable[[list[Parameter]], SetParametersResult]:
    """A set-parameters callback that validates gain changes at run time."""

    def callback(params: list[Parameter]) -> SetParametersResult:
        spec = spec_holder.get("spec")
        for param in params:
            if param.name in GAIN_NAMES and spec is not None:
                try:
                    Gains.from_mapping({**spec.gains.as_dict(), param.name: list(param.value or [])},
                                       len(spec.gains.kp), spec.controller)
                except InvalidInputError as exc:
                    return SetParametersResult(successful=False, reason=str(exc))
            elif param.name in RUN_PARAMETERS and spec is not None:
                return SetParametersResult(
                    successful=False,
                    reason=f"{param.name} defines the run and cannot change while it runs",
                )
        return SetParametersResult(successful=True)

    return callback


def description_json(spec: RunSpec, mode: str) -> str:
    data = spec.describe()
    data["mode"] = mode
    return json.dumps(data, sort_keys=True)


def stamp_to_step(sec: int, nanosec: int, rate: float) -> int:
    """Control step index of a header stamp (stamps are ``k / rate``)."""
    return int(round((sec + nanosec * 1e-9) * rate))


def step_stamp(step: int, rate: float) -> tuple[int, int]:
    """Header stamp ``(sec, nanosec)`` of control step ``step`` (time ``step / rate``)."""
    total_ns = int(round(step * 1e9 / rate))
    return total_ns // 1_000_000_000, total_ns % 1_000_000_000


# --------------------------------------------------------------------------- #
# Process lifecycle
# --------------------------------------------------------------------------- #
def exit_watchdog(seconds: float = 10.0) -> None:
    """Force the process to exit if shutdown hangs (Fast DDS once hung at exit)."""

    def _kill() -> None:
        os._exit(EXIT_FAILURE)

    timer = threading.Timer(seconds, _kill)
    timer.daemon = True
    timer.start()


def run_node(
    name: str,
    factory: Callable[[], Any],
    args: Sequence[str] | None,
) -> int:
    """``main()`` body shared by the nodes (ros2/demos style).

    ``factory`` builds the node after ``rclpy.init``; a ConfigError or
    InvalidInputError while building it is one line on stderr and exit 2.
    The node object must offer ``node`` (the rclpy Node), ``done`` and
    ``exit_code`` attributes and may define ``close()``.
    """
    rclpy.init(args=args)
    wrapper = None
    code = EXIT_OK
    try:
        try:
            wrapper = factory()
        except InvalidInputError as exc:
            print(f"{name}: error: {exc}", file=sys.stderr, flush=True)
            return EXIT_BAD_INPUT
        except PdsmcError as exc:
            print(f"{name}: error: {exc}", file=sys.stderr, flush=True)
            return EXIT_FAILURE
        executor = SingleThreadedExecutor()
        executor.add_node(wrapper.node)
        _install_signal_handlers(wrapper)
        while rclpy.ok() and not wrapper.done:
            executor.spin_once(timeout_sec=0.05)
        code = wrapper.exit_code
    except (KeyboardInterrupt, ExternalShutdownException):
        code = getattr(wrapper, "exit_code", EXIT_OK) if wrapper is not None else EXIT_OK
    finally:
        if wrapper is not None:
            close = getattr(wrapper, "close", None)
            if close is not None:
                close()
            wrapper.node.destroy_node()
        exit_watchdog()
        rclpy.try_shutdown()
    return code


def _install_signal_handlers(wrapper: Any) -> None:
    """SIGINT/SIGTERM end the spin loop; the node's close() then runs."""

    def handler(signum: int, frame: object) -> None:  # noqa: ARG001
        wrapper.done = True
        wrapper.stopped_by_signal = signal.Signals(signum).name

    signal.signal(signal.SIGINT, handler)
    signal.signal(signal.SIGTERM, handler)
