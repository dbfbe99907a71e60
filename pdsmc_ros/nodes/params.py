"""Run parameters of the nodes: one schema, validated on set, applied post-set.

Turns ROS parameters into a :class:`~pdsmc_ros.presets.RunSpec`; nothing here computes
physics, control or metrics.
"""

from __future__ import annotations

import dataclasses
import json
from dataclasses import dataclass
from typing import Any

from rcl_interfaces.msg import ParameterDescriptor, SetParametersResult
from rclpy.exceptions import ParameterUninitializedException
from rclpy.node import Node
from rclpy.parameter import Parameter

from ..checks import are_real, is_real, is_whole
from ..config import choice
from ..control import GAINS, gain_names, law, law_names
from ..errors import ConfigError
from ..presets import RunSpec, contour_names, make_run, smc_reading
from ..robots.catalog import ROBOT_DESCRIPTION, allowed_robots, register_description
from .descriptors import SAFETY_PARAMETERS, declare_busy_wait, descriptor
from .robot_description import receive_robot_description
from .topics import MODES

RUN_PARAMETERS: dict[str, tuple[Any, ParameterDescriptor]] = {
    "robot": ("serial_3r", descriptor("manipulator", constraints="one of: " + allowed_robots())),
    "contour": ("circle", descriptor("contour preset (config/contours.yaml) or csv")),
    "type": ("pdsmc", descriptor("controller type", constraints="one of: " + ", ".join(law_names()))),
    "scenario": ("nominal", descriptor("robustness scenario (config/scenarios.yaml)")),
    "mode": ("lockstep", descriptor("timing mode", constraints="one of: lockstep, realtime")),
    "rate": (0.0, descriptor("control rate in Hz (0: preset, 10 kHz serial / 5 kHz parallel)", lo=0.0, hi=1.0e6)),
    "sample_rate": (0.0, descriptor("statistics rate in Hz (0: thesis value)", lo=0.0, hi=1.0e6)),
    "duration_factor": (1.0, descriptor("multiplies the contour duration", lo=0.001, hi=1000.0)),
    "smc_reading": ("literal", descriptor("SMC model estimate (config/smc_readings.yaml)")),
    "ellipse_error": ("nearest", descriptor("ellipse contour error", constraints="nearest or osculating")),
    "waypoints_file": ("", descriptor("CSV of task-space waypoints for contour csv")),
    "segment_duration": (2.0, descriptor("seconds per CSV segment", lo=0.001, hi=1000.0)),
    "clock_rate": (100.0, descriptor("lockstep: /clock publication rate in sim-time Hz", lo=1.0, hi=1.0e6)),
}
STABILITY_PARAMETERS: dict[str, tuple[Any, ParameterDescriptor]] = {
    "stability_margin": (0.0, descriptor(
        "required control rate / lowest stable rate of the gains (0: the mode's, 2 realtime, 1 lockstep)",
        lo=0.0, hi=1.0e6)),
    "delay_periods": (0, ParameterDescriptor(
        description="periods of delay beyond the mode's own that the stability check models (a driver's)",
        additional_constraints="a whole number in [0, 1000]", dynamic_typing=True)),
}
"""The controller's: what :func:`~pdsmc_ros.control.stability.check_rate` requires of its gains."""


@dataclass(frozen=True)
class NodeRun:
    """What every node starts from: the run its parameters name, the mode and the busy-wait;
    for the controller, ``stability``: the keywords of
    :func:`~pdsmc_ros.control.stability.check_rate` its gains must pass."""

    spec: RunSpec
    mode: str
    busy_wait: float
    stability: dict[str, Any] = dataclasses.field(default_factory=dict)


def declare_node_run(node: Node, *, gains: bool = False) -> NodeRun:
    """The start-up lines of every node: declare the run's parameters (and the gains) and
    ``busy_wait``, and build the RunSpec they name (a ConfigError if bad). ``gains``: the node
    needs them (the controller: no preset and none given is an error; it also declares
    :data:`STABILITY_PARAMETERS`); the other nodes accept them and run without. A node whose run
    cannot change adds :func:`refuse_run_changes` once all its parameters are declared."""
    declare_run_parameters(node, gains=gains)
    busy_wait = declare_busy_wait(node)  # used in real time
    if node.get_parameter("robot").value == ROBOT_DESCRIPTION:
        try:
            register_description(receive_robot_description(node))
        except ConfigError as exc:
            raise ConfigError(f"parameter robot: {exc}") from None
    spec = run_spec_from_parameters(node, needs_gains=gains)
    mode = str(node.get_parameter("mode").value)
    stability = stability_from_parameters(node, mode) if gains else {}
    return NodeRun(spec, mode, busy_wait, stability)


def stability_from_parameters(node: Node, mode: str) -> dict[str, Any]:
    """``check_rate``'s keywords from ``stability_margin`` and ``delay_periods`` (ConfigError if bad)."""
    margin = node.get_parameter("stability_margin").value
    if not is_real(margin) or not 0.0 <= margin <= 1.0e6:
        raise ConfigError(f"parameter stability_margin must be a number >= 0 (0: the mode's), got {margin!r}")
    delay = node.get_parameter("delay_periods").value
    if not is_whole(delay) or not 0 <= delay <= 1000:
        raise ConfigError(f"parameter delay_periods must be a whole number in [0, 1000], got {delay!r}")
    return {"mode": mode, "delay_periods": delay, "margin": float(margin) or None, "entry": "node"}


def _range_of(name: str) -> tuple[float, float]:
    ranges = RUN_PARAMETERS[name][1].floating_point_range
    if ranges:
        return ranges[0].from_value, ranges[0].to_value
    return float("-inf"), float("inf")


def declare_run_parameters(node: Node, *, gains: bool = False) -> None:
    """Declare the parameters that define a run and the gains (every node: one params file or
    ``-p kp:=`` serves all; only the controller uses them) and, for the controller (``gains``),
    :data:`STABILITY_PARAMETERS`."""
    for name, (default, desc) in RUN_PARAMETERS.items():
        node.declare_parameter(name, default, desc)
    for name, spec in GAINS.items():  # every gain a registered law declares (one params file for all)
        node.declare_parameter(name, None, descriptor(spec.help()))
    if gains:
        for name, (default, desc) in STABILITY_PARAMETERS.items():
            node.declare_parameter(name, default, desc)


def run_spec_from_parameters(node: Node, *, needs_gains: bool = True) -> RunSpec:
    """Build and validate the RunSpec named by the node's parameters.

    The gains given (``-p kp:=``, a params file: rcl merges both) are the overrides layer of
    :func:`~pdsmc_ros.presets.make_run`, the one builder ``pdsmc simulate`` uses too: they
    replace the preset's, then the scenario's gain factors apply (``scenario:=high_pd`` scales
    them the same way in-process and in the nodes). An arm without preset gains needs them all
    given when ``needs_gains`` (the controller); the other nodes run with neutral placeholders.

    Raises
    ------
    InvalidInputError
        With a message naming the parameter and what is allowed.
    """
    p = {}
    for name, (default, _desc) in RUN_PARAMETERS.items():
        value = node.get_parameter(name).value
        if isinstance(default, str):
            if not isinstance(value, str):
                raise ConfigError(f"parameter {name} must be a string, got {value!r}")
        else:
            if not is_real(value):
                raise ConfigError(f"parameter {name} must be a number, got {value!r}")
            value = float(value)
            lo, hi = _range_of(name)
            if not lo <= value <= hi:
                raise ConfigError(f"parameter {name} must be in [{lo:g}, {hi:g}], got {value:g}")
        p[name] = value
    if p["mode"] not in MODES:
        raise ConfigError(f"parameter mode: unknown value {p['mode']!r}; choose one of: lockstep, realtime")
    overrides = {}
    for name in gain_names():
        if not node.has_parameter(name):
            continue
        try:
            value = node.get_parameter(name).value
        except ParameterUninitializedException:
            continue  # not given: the preset applies
        if is_real(value):
            value = [value]  # a scalar gain given as a number
        if value is not None and len(value) > 0:
            if not are_real(value):
                raise ConfigError(f"parameter {name} must be a list of numbers, got {value!r}")
            overrides[name] = [float(v) for v in value]
    try:
        choice(p["contour"], contour_names(p["robot"]), f"contour for {p['robot']}")
        spec = make_run(p["robot"], p["contour"], p["type"], scenario=p["scenario"], rate=p["rate"] or None,
                        sample_rate=p["sample_rate"] or None,
                        smc_model=smc_reading(p["smc_reading"]) if law(p["type"]).model_based else None,
                        ellipse_error=p["ellipse_error"], waypoints_file=p["waypoints_file"] or None,
                        segment_duration=p["segment_duration"], overrides=overrides, needs_gains=needs_gains)
    except ConfigError as exc:
        raise ConfigError(f"parameters: {exc}") from None
    if p["duration_factor"] != 1.0:
        spec = dataclasses.replace(spec, duration_factor=spec.duration_factor * p["duration_factor"])
    return spec


def description_json(spec: RunSpec, mode: str) -> str:
    data = spec.describe()
    data["mode"] = mode
    return json.dumps(data, sort_keys=True)


def refuse_run_changes(params: list[Parameter]) -> SetParametersResult:
    """Set-parameters callback of the plant, trajectory and recorder: a run's definition
    is fixed while it runs."""
    for param in params:
        if param.name in RUN_PARAMETERS or param.name in SAFETY_PARAMETERS or param.name == "output":
            return SetParametersResult(
                successful=False, reason=f"{param.name} defines the run and cannot change while it runs"
            )
    return SetParametersResult(successful=True)
