"""Run parameters of the nodes: one schema, validated on set, applied post-set.

Turns ROS parameters into a :class:`~pdsmc_ros.presets.RunSpec`; nothing here computes
physics, control or metrics.
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from rcl_interfaces.msg import (
    FloatingPointRange,
    ParameterDescriptor,
    SetParametersResult,
)
from rclpy.exceptions import (
    ParameterUninitializedException,
)
from rclpy.node import Node
from rclpy.parameter import Parameter

from ..config import choice
from ..control import GAINS, Gains, gain_names, law, law_names
from ..control.safety import MAX_SAFE_DAMPING, MAX_SAFE_STIFFNESS, SafetyConfig
from ..errors import ConfigError, InvalidInputError
from ..presets import RunSpec, contour_names, make_run, scenario_gain_factors, smc_reading
from ..robots.catalog import ROBOT_DESCRIPTION, allowed_robots, register_description
from .topics import MODES

BUSY_WAIT_S = 0.0002  # real time: default busy-wait before a tick (parameter busy_wait)


def _descriptor(
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


RUN_PARAMETERS: dict[str, tuple[Any, ParameterDescriptor]] = {
    "robot": ("serial_3r", _descriptor("manipulator", constraints="one of: " + allowed_robots())),
    "contour": ("circle", _descriptor("contour preset (config/contours.yaml) or csv")),
    "type": ("pdsmc", _descriptor("controller type", constraints="one of: " + ", ".join(law_names()))),
    "scenario": ("nominal", _descriptor("robustness scenario (config/scenarios.yaml)")),
    "mode": ("lockstep", _descriptor("timing mode", constraints="one of: lockstep, realtime")),
    "rate": (0.0, _descriptor("control rate in Hz (0: preset, 10 kHz serial / 5 kHz parallel)", lo=0.0, hi=1.0e6)),
    "sample_rate": (0.0, _descriptor("statistics rate in Hz (0: thesis value)", lo=0.0, hi=1.0e6)),
    "duration_factor": (1.0, _descriptor("multiplies the contour duration", lo=0.001, hi=1000.0)),
    "smc_reading": ("literal", _descriptor("SMC model estimate (config/smc_readings.yaml)")),
    "ellipse_error": ("nearest", _descriptor("ellipse contour error", constraints="nearest or osculating")),
    "waypoints_file": ("", _descriptor("CSV of task-space waypoints for contour csv")),
    "segment_duration": (2.0, _descriptor("seconds per CSV segment", lo=0.001, hi=1000.0)),
    "clock_rate": (100.0, _descriptor("lockstep: /clock publication rate in sim-time Hz", lo=1.0, hi=1.0e6)),
}
STABILITY_PARAMETERS: dict[str, tuple[Any, ParameterDescriptor]] = {
    "stability_margin": (0.0, _descriptor(
        "required control rate / lowest stable rate of the gains (0: the mode's, 2 realtime, 1 lockstep)",
        lo=0.0, hi=1.0e6)),
    "delay_periods": (0, ParameterDescriptor(
        description="periods of delay beyond the mode's own that the stability check models (a driver's)",
        additional_constraints="a whole number in [0, 1000]", dynamic_typing=True)),
}
"""The controller's: what :func:`~pdsmc_ros.control.stability.check_rate` requires of its gains."""


SAFETY_PARAMETERS: dict[str, tuple[Any, ParameterDescriptor]] = {
    "watchdog_timeout": (2.0, _descriptor(
        "lockstep: wall-clock seconds without effort before safe mode (checked every 20 ms)", lo=0.05, hi=3600.0)),
    "watchdog_periods": (20, _descriptor("real time: control periods without effort before safe mode")),
    "safe_mode": ("damp", _descriptor("safe mode", constraints="damp (braking only) or hold (hold position)")),
    "safe_damping": (5.0, _descriptor("safe-mode braking gain in N m s/rad", lo=0.0, hi=MAX_SAFE_DAMPING)),
    "safe_stiffness": (200.0, _descriptor("hold-mode stiffness in N m/rad", lo=0.0, hi=MAX_SAFE_STIFFNESS)),
    "on_controller_loss": ("resume", _descriptor("after safe mode", constraints="resume or end")),
    "safe_time_scale": (1.0, _descriptor(
        "lockstep: sim seconds the plant advances per wall second in safe mode (1: real time, 0: frozen)",
        lo=0.0, hi=1000.0)),
}


def refuse_run_changes(params: list[Parameter]) -> SetParametersResult:
    """Set-parameters callback of the plant, trajectory and recorder: a run's definition
    is fixed while it runs."""
    for param in params:
        if param.name in RUN_PARAMETERS or param.name in SAFETY_PARAMETERS or param.name == "output":
            return SetParametersResult(
                successful=False, reason=f"{param.name} defines the run and cannot change while it runs"
            )
    return SetParametersResult(successful=True)


def declare_safety_parameters(node: Node) -> None:
    for name, (default, desc) in SAFETY_PARAMETERS.items():
        node.declare_parameter(name, default, desc)


def safety_from_parameters(node: Node) -> SafetyConfig:
    """The plant's SafetyConfig, validated (ConfigError naming the parameter)."""
    values = {name: node.get_parameter(name).value for name in SAFETY_PARAMETERS}
    for name in ("watchdog_timeout", "safe_damping", "safe_stiffness", "safe_time_scale"):
        if isinstance(values[name], bool) or not isinstance(values[name], (int, float)):
            raise ConfigError(f"parameter {name} must be a number, got {values[name]!r}")
    if not 0.0 <= values["safe_time_scale"] <= 1000.0:
        raise ConfigError(f"parameter safe_time_scale must be in [0, 1000], got {values['safe_time_scale']!r}")
    if isinstance(values["watchdog_periods"], bool) or not isinstance(values["watchdog_periods"], int) \
            or values["watchdog_periods"] < 1:
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
    if isinstance(value, bool) or not isinstance(value, int) or not lo <= value <= hi:
        raise ConfigError(f"parameter {name} must be a whole number in [{lo}, {hi}], got {value!r}")
    return value


def declare_busy_wait(node: Node) -> float:
    """Declare ``busy_wait`` and return it: real time, seconds before each tick spent
    busy-waiting instead of sleeping (see :func:`_serve_loop`); a ConfigError if bad."""
    node.declare_parameter("busy_wait", BUSY_WAIT_S, _descriptor(
        "real time: seconds before each tick spent busy-waiting instead of sleeping (absorbs late "
        "wake-ups, costs that share of a core; a process running every ticking node: up to the whole period)",
        lo=0.0, hi=1.0))
    value = node.get_parameter("busy_wait").value
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not 0.0 <= value <= 1.0:
        raise ConfigError(f"parameter busy_wait must be a number of seconds in [0, 1], got {value!r}")
    return float(value)


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
    if isinstance(margin, bool) or not isinstance(margin, (int, float)) or not 0.0 <= margin <= 1.0e6:
        raise ConfigError(f"parameter stability_margin must be a number >= 0 (0: the mode's), got {margin!r}")
    delay = node.get_parameter("delay_periods").value
    if isinstance(delay, bool) or not isinstance(delay, int) or not 0 <= delay <= 1000:
        raise ConfigError(f"parameter delay_periods must be a whole number in [0, 1000], got {delay!r}")
    return {"mode": mode, "delay_periods": delay, "margin": float(margin) or None, "entry": "node"}


ROBOT_DESCRIPTION_WAIT_S = 60.0
"""How long a node given ``robot:=/robot_description`` waits for it (a node composed before the
plant that publishes it would wait in vain: run such nodes in their own processes)."""


def receive_robot_description(node: Node, timeout_s: float = ROBOT_DESCRIPTION_WAIT_S) -> str:
    """The URDF on ``/robot_description`` (transient local, as robot_state_publisher offers it).

    Raises
    ------
    ConfigError
        If none arrives within ``timeout_s``.
    """
    import time

    import rclpy
    from std_msgs.msg import String

    from .topics import LATCHED_QOS, TOPIC_ROBOT_DESCRIPTION

    received: list[str] = []
    subscription = node.create_subscription(String, TOPIC_ROBOT_DESCRIPTION, lambda msg: received.append(msg.data),
                                            LATCHED_QOS)
    node.get_logger().info(f"waiting for the arm on {ROBOT_DESCRIPTION}")
    deadline = time.monotonic() + timeout_s
    try:
        while not received and time.monotonic() < deadline:
            rclpy.spin_once(node, timeout_sec=0.1)
    finally:
        node.destroy_subscription(subscription)
    if not received:
        raise ConfigError(f"{ROBOT_DESCRIPTION}: nothing received within {timeout_s:g} s (is a "
                          "robot_state_publisher or a pdsmc_ros plant running?)")
    return received[-1]


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
        node.declare_parameter(name, None, _descriptor(spec.help()))
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
            if isinstance(value, bool) or not isinstance(value, (int, float)):
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
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            value = [value]  # a scalar gain given as a number
        if value is not None and len(value) > 0:
            if isinstance(value, str) or not all(
                isinstance(v, (int, float)) and not isinstance(v, bool) for v in value
            ):
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


class GainUpdates:
    """Run-time gain changes, ros2/demos style: the on-set callback validates, the
    post-set callback applies.

    A change passes exactly the checks of start-up (:meth:`Gains.from_mapping`
    and the zero-order-hold stability check at the running rate,
    :func:`~pdsmc_ros.control.stability.check_rate`) or is refused with the reason
    (``ros2 param set`` shows it: for an unstable gain, the lowest stable
    rate). ``apply`` receives the accepted gains only after the parameters are
    set, from the post-set callback.
    """

    def __init__(self, node: Node, spec: RunSpec, check: Callable[[RunSpec], object],
                 apply: Callable[[Gains], None]) -> None:
        self.spec = spec
        self.check = check
        self.apply = apply
        self.pending: Gains | None = None
        node.add_on_set_parameters_callback(self.validate)
        node.add_post_set_parameters_callback(self.applied)

    def validate(self, params: list[Parameter]) -> SetParametersResult:
        merged = self.spec.gains.as_dict()
        factors = scenario_gain_factors(self.spec.scenario, self.spec.controller)
        changed = False
        for param in params:
            if param.name in GAINS:
                value = param.value
                scalar = isinstance(value, (int, float)) and not isinstance(value, bool)
                merged[param.name] = [value] if scalar else list(value or [])
                changed = True
            elif param.name in RUN_PARAMETERS or param.name in ("joints", "autostart"):
                return SetParametersResult(
                    successful=False,
                    reason=f"{param.name} defines the run and cannot change while it runs",
                )
        self.pending = None
        if not changed:
            return SetParametersResult(successful=True)
        try:
            gains = Gains.from_mapping({k: v for k, v in merged.items() if v}, self.spec.gains.n,
                                       self.spec.controller)
            # as at start: the scenario's factors apply to the gains given
            gains = gains.scaled({k: f for k, f in factors.items() if any(p.name == k for p in params)})
            self.check(dataclasses.replace(self.spec, gains=gains))
        except (InvalidInputError, TypeError) as exc:
            return SetParametersResult(successful=False, reason=str(exc))
        self.pending = gains
        return SetParametersResult(successful=True)

    def applied(self, params: list[Parameter]) -> None:
        if self.pending is None or not any(p.name in GAINS for p in params):
            return
        gains, self.pending = self.pending, None
        self.spec = dataclasses.replace(self.spec, gains=gains)
        self.apply(gains)


def description_json(spec: RunSpec, mode: str) -> str:
    data = spec.describe()
    data["mode"] = mode
    return json.dumps(data, sort_keys=True)


def decimation(rate: float, target: float) -> int:
    """Publish every ``decimation`` steps so a ``rate`` Hz loop emits at most ``target`` Hz."""
    return max(1, int(round(rate / target)))
