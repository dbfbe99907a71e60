"""Shared plumbing of the pdsmc_ros nodes: run parameters, QoS, topics, lifecycle.

Nothing here computes physics, control or metrics; it only turns ROS
parameters into a :class:`~pdsmc_ros.presets.RunSpec` and wires messages.
"""

from __future__ import annotations

import dataclasses
import faulthandler
import gc
import json
import math
import signal
import sys
import threading
import time
from collections import deque
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
import rclpy
from rcl_interfaces.msg import FloatingPointRange, ParameterDescriptor, SetParametersResult
from rclpy.clock import Clock, ClockType
from rclpy.duration import Duration
from rclpy.exceptions import (
    InvalidParameterTypeException,
    ParameterException,
    ParameterUninitializedException,
)
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy_impl
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.serialization import serialize_message

from ..errors import ConfigError, InvalidInputError, PdsmcError
from ..safety import MAX_SAFE_DAMPING, MAX_SAFE_STIFFNESS, SafetyConfig
from ..presets import (
    CONTROLLER_NAMES,
    GAIN_NAMES,
    ROBOT_NAMES,
    Gains,
    RunSpec,
    make_run,
)
from . import intra

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
TOPIC_JOINT_TRAJECTORY = "~/joint_trajectory"  # joint_trajectory_controller's topic interface
TOPIC_ROBOT_DESCRIPTION = "robot_description"

MODES = ("lockstep", "realtime")

# Subscriptions of the lockstep loop and the recorder: every sample, in order (reliable,
# keep-all; a shallow keep-last queue lost data).
LOCKSTEP_QOS = QoSProfile(
    reliability=ReliabilityPolicy.RELIABLE,
    history=HistoryPolicy.KEEP_ALL,
    durability=DurabilityPolicy.VOLATILE,
)
# Publishers of the loop: reliable with a deep but bounded history. A keep-all writer
# blocks in publish() once a subscriber stops acknowledging (a killed node, until DDS
# drops it, or a new node still starting): that froze the plant in safe mode. A live
# subscriber acknowledges each sample long before 10,000 newer ones are written.
STREAM_DEPTH = 10_000
STREAM_QOS = QoSProfile(
    reliability=ReliabilityPolicy.RELIABLE,
    history=HistoryPolicy.KEEP_LAST,
    depth=STREAM_DEPTH,
    durability=DurabilityPolicy.VOLATILE,
)
# Real time: a controller acts on the newest sample; a queue of old ones is only delay.
LATEST_QOS = QoSProfile(
    reliability=ReliabilityPolicy.RELIABLE,
    history=HistoryPolicy.KEEP_LAST,
    depth=1,
    durability=DurabilityPolicy.VOLATILE,
)


# The run description is published once and must reach late joiners.
LATCHED_QOS = QoSProfile(
    reliability=ReliabilityPolicy.RELIABLE,
    history=HistoryPolicy.KEEP_LAST,
    depth=1,
    durability=DurabilityPolicy.TRANSIENT_LOCAL,
)

# Standard trajectories (joint_trajectory_controller subscribes with the system default QoS:
# reliable, volatile, keep last 10)
TRAJECTORY_QOS = QoSProfile(
    reliability=ReliabilityPolicy.RELIABLE,
    history=HistoryPolicy.KEEP_LAST,
    depth=10,
    durability=DurabilityPolicy.VOLATILE,
)

# Start-up polling must not wait for /clock, which starts only once everyone is there.
STEADY_CLOCK = Clock(clock_type=ClockType.STEADY_TIME)

EXIT_OK = 0
EXIT_FAILURE = 1
EXIT_BAD_INPUT = 2


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
    "clock_rate": (100.0, _descriptor("lockstep: /clock publication rate in sim-time Hz", lo=1.0, hi=1.0e6)),
}
GAIN_DESCRIPTIONS = {
    "kp": "proportional gains Kp, one per joint (empty: preset of Table 4.16 / 4.33)",
    "kd": "derivative gains Kd, one per joint (empty: preset)",
    "ks": "switching gains Ks, one per joint (empty: preset)",
    "lam": "sliding-surface slopes lambda, one per joint (empty: preset)",
    "phi": "boundary layers phi > 0, one per joint (empty: preset)",
}


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


def torque_limit_from_parameters(node: Node, n: int) -> np.ndarray | None:
    """``torque_limit`` (one positive number per joint, or unset), validated."""
    value = node.get_parameter("torque_limit").value
    if value is None or (not isinstance(value, str) and len(value) == 0):
        return None
    if isinstance(value, str) or not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in value):
        raise ConfigError(f"parameter torque_limit must be a list of {n} numbers, got {value!r}")
    limit = np.asarray(value, dtype=float)
    if limit.shape != (n,) or not np.all(np.isfinite(limit)) or np.any(limit <= 0):
        raise ConfigError(f"parameter torque_limit needs {n} finite values > 0 (N m), got {list(value)}")
    return limit


def _range_of(name: str) -> tuple[float, float]:
    ranges = RUN_PARAMETERS[name][1].floating_point_range
    if ranges:
        return ranges[0].from_value, ranges[0].to_value
    return float("-inf"), float("inf")


def declare_run_parameters(node: Node, *, gains: bool = False) -> None:
    """Declare the parameters that define a run (and the gains, for the controller)."""
    for name, (default, desc) in RUN_PARAMETERS.items():
        node.declare_parameter(name, default, desc)
    if gains:
        for name in GAIN_NAMES:
            node.declare_parameter(name, None, _descriptor(GAIN_DESCRIPTIONS[name]))


def run_spec_from_parameters(node: Node) -> RunSpec:
    """Build and validate the RunSpec named by the node's parameters.

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
        spec = dataclasses.replace(spec, duration_factor=spec.duration_factor * p["duration_factor"])
    overrides = {}
    for name in GAIN_NAMES:
        if not node.has_parameter(name):
            continue
        try:
            value = node.get_parameter(name).value
        except ParameterUninitializedException:
            continue  # not given: the preset applies
        if value is not None and len(value) > 0:
            if isinstance(value, str) or not all(
                isinstance(v, (int, float)) and not isinstance(v, bool) for v in value
            ):
                raise ConfigError(f"parameter {name} must be a list of numbers, got {value!r}")
            overrides[name] = [float(v) for v in value]
    if overrides:
        merged = {**spec.gains.as_dict(), **overrides}
        n = len(spec.gains.kp)
        gains = Gains.from_mapping(merged, n, spec.controller)
        spec = dataclasses.replace(spec, gains=gains)
    return spec


class GainUpdates:
    """Run-time gain changes, ros2/demos style: the on-set callback validates, the
    post-set callback applies.

    A change passes exactly the checks of start-up (:meth:`Gains.from_mapping`
    and the zero-order-hold stability check at the running rate,
    :func:`~pdsmc_ros.stability.check_rate`) or is refused with the reason
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
        changed = False
        for param in params:
            if param.name in GAIN_NAMES:
                merged[param.name] = list(param.value or [])
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
            gains = Gains.from_mapping(
                {k: v for k, v in merged.items() if v}, len(self.spec.gains.kp), self.spec.controller
            )
            self.check(dataclasses.replace(self.spec, gains=gains))
        except (InvalidInputError, TypeError) as exc:
            return SetParametersResult(successful=False, reason=str(exc))
        self.pending = gains
        return SetParametersResult(successful=True)

    def applied(self, params: list[Parameter]) -> None:
        if self.pending is None or not any(p.name in GAIN_NAMES for p in params):
            return
        gains, self.pending = self.pending, None
        self.spec = dataclasses.replace(self.spec, gains=gains)
        self.apply(gains)


RCLError = _rclpy_impl.RCLError


class GuardedPublisher:
    """A publisher whose failures (e.g. a dead reliable subscriber not yet dropped)
    are logged, throttled, and counted instead of killing the node."""

    def __init__(self, publisher: Any, node: Node) -> None:
        self.publisher = publisher
        self.node = node
        self.failures = 0
        self._handle = publisher.handle
        # composed with --intra-process: local subscribers get the bytes directly (nodes.intra)
        domain = intra.current()
        self._route = None if domain is None else domain.add_publisher(
            publisher, publisher.msg_type, publisher.qos_profile)

    def publish(self, msg: Any) -> bool:
        try:
            route = self._route
            if type(msg) is bytes:  # the loop's serialized messages: straight to rcl
                if route is None or route.deliver(msg):
                    with self._handle:
                        self._handle.publish_raw(msg)
            else:
                data = serialize_message(msg) if route is not None and route.queues else b""
                if route is None or route.deliver(data):
                    self.publisher.publish(msg)
            return True
        except RCLError as exc:
            self.failures += 1
            if self.failures <= 5 or self.failures % 1000 == 0:
                self.node.get_logger().error(
                    f"publish on {self.publisher.topic_name} failed ({self.failures} so far): {exc}")
            return False

    def get_subscription_count(self) -> int:
        """Matched subscribers: over DDS, plus those in this process on the intra-process path."""
        if self._route is None:
            return self.publisher.get_subscription_count()
        return self._route.refresh() + len(self._route.queues)


def description_json(spec: RunSpec, mode: str) -> str:
    data = spec.describe()
    data["mode"] = mode
    return json.dumps(data, sort_keys=True)


def decimation(rate: float, target: float) -> int:
    """Publish every ``decimation`` steps so a ``rate`` Hz loop emits at most ``target`` Hz."""
    return max(1, int(round(rate / target)))


# --------------------------------------------------------------------------- #
# Process lifecycle
# --------------------------------------------------------------------------- #
TEARDOWN_TIMEOUT_S = 4.0  # below the orchestration's 5 s between SIGINT and SIGKILL
DRAIN_TIMEOUT_S = 2.0  # at most this long for subscribers to acknowledge the last messages


# Exit status of a node whose work was done but whose DDS teardown hung: its teardown watch
# ends it with SIGALRM (128 + 14 to the shell). scripts/run_experiment.sh reports it as a
# warning, not a failure: the node's outputs were complete before the hang.
EXIT_TEARDOWN_HUNG = 128 + signal.SIGALRM


def arm_teardown_watch(code: int, seconds: float = TEARDOWN_TIMEOUT_S) -> None:
    """End the process, with every thread's stack on stderr, if it has not ended in ``seconds``.

    Armed once the node's work is saved, before DDS entities are destroyed and
    the interpreter finalises (Fast DDS in these wheels hangs there now and
    then, once in a destroy_node). The stack dump runs in faulthandler's own C
    thread, so it fires even when the hang holds the GIL, and names where the
    process was stuck. If the work ended well (``code`` 0) the process is then
    ended by SIGALRM's default action, which needs no Python either, so the
    orchestration can tell a hang after a complete run (:data:`EXIT_TEARDOWN_HUNG`)
    from a failure; otherwise faulthandler exits with status 1. It stays armed
    until the process ends: :func:`run_nodes` is a process entry point.
    """
    if code == EXIT_OK:
        faulthandler.dump_traceback_later(seconds, exit=False, file=sys.__stderr__)
        signal.signal(signal.SIGALRM, signal.SIG_DFL)
        signal.setitimer(signal.ITIMER_REAL, seconds + 0.2)
    else:
        faulthandler.dump_traceback_later(seconds, exit=True, file=sys.__stderr__)


class UpstreamWatch:
    """Real time: notice that every publisher of a topic has gone after the run began.

    A real-time node cannot tell the plant's last message from any other; when
    the plant leaves (its participant is removed from the graph), the node
    downstream of it is done, even if that last message was never delivered.
    The owner calls :meth:`poll` from its tick, after the tick's work; it reads
    the graph cache (``count_publishers``) at most every ``period`` seconds. (An
    executor timer did this at first: each of its turns took the GIL for about
    half a millisecond and made every hundredth controller period late.)
    """

    def __init__(self, node: Node, topic: str, on_gone: Callable[[], None], *,
                 period: float = 0.1) -> None:
        self.node = node
        self.topic = node.resolve_topic_name(topic)
        self.on_gone = on_gone
        self.period = period
        self.seen = False
        self.gone = False
        self.next_check = 0.0

    def poll(self) -> None:
        now = time.perf_counter()
        if self.gone or now < self.next_check:
            return
        self.next_check = now + self.period
        self.check()

    def check(self) -> None:
        if self.node.count_publishers(self.topic):
            self.seen = True
        elif self.seen:
            self.gone = True
            self.on_gone()


def end_when_plant_leaves(wrapper: Any, received: Callable[[], int]) -> UpstreamWatch:
    """Real time: once the plant has left, no state will come, so ``wrapper`` is done.

    ``received()`` gives the number of states the node received, for the log line.
    Composed with the plant in one process, the plant's node stays in the graph
    until the process ends: :class:`_Group` calls the watch's ``on_gone`` once
    the plant is done instead.
    """

    def on_gone() -> None:
        if not wrapper.done:
            wrapper.node.get_logger().info(f"the plant has left ({received()} states received); stopping")
            wrapper.done = True

    return UpstreamWatch(wrapper.node, TOPIC_JOINT_STATES, on_gone)


class Inputs:
    """The subscriptions of a node's control loop, taken as serialized CDR.

    They live on a lean companion node (``<name>_io``: no parameter services,
    no rosout) that no executor sees; :func:`run_nodes` takes their messages
    with a hand-driven wait set and calls the handlers directly, while the
    executor serves the node's timers, parameters and ``/clock`` in between.
    That path sets the lockstep rate (bench/lockstep.py) and the real-time
    jitter. Handlers receive the serialized message (:mod:`pdsmc_ros.bag.cdr`).
    QoS: every sample in lockstep, the newest in real time, unless given.

    ``batch_s`` > 0 makes the inputs an observer's: once woken, the loop lets
    messages gather for ``batch_s`` before it takes them again, so a node off
    the loop's critical path (the recorder) wakes a few hundred times a second
    instead of once per message, and leaves the cores to the nodes that are
    on it. Its subscriptions must keep every sample (keep-all or deep queues),
    and its handlers receive the messages of a batch as one list, in order.
    """

    def __init__(self, node: Node, mode: str, *, batch_s: float = 0.0, suffix: str = "_io") -> None:
        if not 0.0 <= batch_s <= MAX_BATCH_S:
            raise ValueError(f"batch_s must be in [0, {MAX_BATCH_S}] s, got {batch_s!r}")
        self.node = node
        self.mode = mode
        self.batch_s = batch_s
        self.suffix = suffix  # of the companion node's name (one per Inputs of a node)
        self.io_node: Node | None = None
        self.hot: list[tuple[Any, Callable[[bytes], None]]] = []
        # composed with --intra-process: inputs published in this process (nodes.intra)
        self.local: list[tuple[deque, Callable[[bytes], None]]] = []

    def subscribe(self, msg_type: Any, topic: str, handler: Callable[[bytes], None],
                  qos: QoSProfile | None = None) -> None:
        if qos is None:
            qos = LOCKSTEP_QOS if self.mode == "lockstep" else LATEST_QOS
        domain = intra.current()
        if domain is None:
            self._subscribe_dds(msg_type, topic, handler, qos)
            return
        domain.add_subscription(
            self.node.resolve_topic_name(topic), msg_type, qos,
            local=lambda queue: self.local.append((queue, handler)),
            dds=lambda: self._subscribe_dds(msg_type, topic, handler, qos))

    def _subscribe_dds(self, msg_type: Any, topic: str, handler: Callable[[bytes], None],
                       qos: QoSProfile) -> None:
        if self.io_node is None:
            # no global arguments: the companion must not get use_sim_time (a /clock
            # subscription nobody serves); topics are resolved by the node itself
            self.io_node = Node(f"{self.node.get_name()}{self.suffix}", namespace=self.node.get_namespace(),
                                context=self.node.context, use_global_arguments=False,
                                start_parameter_services=False, enable_rosout=False)
        name = self.node.resolve_topic_name(topic)
        sub = self.io_node.create_subscription(msg_type, name, _taken_by_wait_set, qos, raw=True)
        self.hot.append((sub, handler))

    def destroy(self) -> None:
        if self.io_node is not None:
            self.io_node.destroy_node()
            self.io_node = None


def _taken_by_wait_set(_msg: bytes) -> None:  # pragma: no cover - never called
    """Callback of a lockstep input: its messages are taken by run_nodes' wait set."""


def run_node(
    name: str,
    factory: Callable[[], Any],
    args: Sequence[str] | None,
) -> int:
    """``main()`` body shared by the nodes (ros2/demos style).

    ``factory`` builds the node after ``rclpy.init``; a ConfigError or
    InvalidInputError while building it is one line on stderr and exit 2.
    The node object must offer ``node`` (the rclpy Node), ``done`` and
    ``exit_code`` attributes and may define ``close()``, ``period`` and ``tick()``.
    """
    return run_nodes(name, [factory], args)


def run_nodes(
    name: str,
    factories: Sequence[Callable[[], Any]],
    args: Sequence[str] | None,
    *,
    intra_process: bool = False,
) -> int:
    """Run one or several node wrappers in this process with one executor.

    Several wrappers make the composed mode (the nodes stay separate rclpy
    nodes, as in a component container). They are closed in reverse order of
    creation, so a recorder created first is closed last. ``intra_process``
    hands the loop's messages between them without DDS (:mod:`.intra`).
    """
    rclpy.init(args=args)
    wrappers: list[Any] = []
    executor: SingleThreadedExecutor | None = None
    domain = intra.IntraProcess(rclpy.get_default_context()) if intra_process else None
    code = EXIT_OK
    # our handlers from the start: a signal arriving while rclpy builds a node or the executor
    # would otherwise interrupt its __init__ (and rclpy's __del__ of the half-built object
    # prints a traceback); it is noted here and ends the loop as soon as the loop starts
    signalled = _SignalNote()
    _install_signal_handlers(signalled)
    try:
        try:
            intra.activate(domain)
            for factory in factories:
                wrappers.append(factory())
            if domain is not None:
                domain.bind()
        except (InvalidInputError, ParameterException, InvalidParameterTypeException, ValueError,
                TypeError) as exc:
            print(f"{name}: error: {exc}", file=sys.stderr, flush=True)
            code = EXIT_BAD_INPUT  # also what the teardown watch is armed with
            return code
        except PdsmcError as exc:
            print(f"{name}: error: {exc}", file=sys.stderr, flush=True)
            code = EXIT_FAILURE
            return code
        finally:
            intra.activate(None)
        group = _Group(wrappers)
        period = group.period
        # The loop's messages go through a hand-driven wait set (Inputs), the rest through
        # the executor between them. Real-time nodes are paced by the loop, not by rclpy
        # timers (they fired 35x too often under this wheel's EventsExecutor and wake
        # late under the default one).
        executor = SingleThreadedExecutor()
        for wrapper in wrappers:
            executor.add_node(wrapper.node)
        if signalled.stopped_by_signal:
            group.done, group.stopped_by_signal = True, signalled.stopped_by_signal
        _install_signal_handlers(group)
        with_inputs = [inputs for w in wrappers for inputs in _inputs_of(w)]
        # the loop's own inputs are taken at every pass; observers' (composed or alone) in batches
        loop_inputs = [item for inputs in with_inputs if not inputs.batch_s for item in inputs.hot]
        observed = [item for inputs in with_inputs if inputs.batch_s for item in inputs.hot]
        observe_every = min((inputs.batch_s for inputs in with_inputs if inputs.batch_s), default=0.0)
        local = _LocalInputs(
            [item for inputs in with_inputs if not inputs.batch_s for item in inputs.local],
            [item for inputs in with_inputs if inputs.batch_s for item in inputs.local],
            None if domain is None else domain.guard)
        _serve_loop(executor, group, loop_inputs, period, observed, observe_every, local,
                    busy_wait=group.busy_wait)
        code = group.exit_code
        if not group.stopped_by_signal:
            _drain(executor, wrappers)
    except (KeyboardInterrupt, ExternalShutdownException):
        code = max((getattr(w, "exit_code", EXIT_OK) for w in wrappers), default=EXIT_OK)
    finally:
        for wrapper in reversed(wrappers):
            close = getattr(wrapper, "close", None)
            if close is not None:
                close()
        arm_teardown_watch(code)
        if executor is not None:
            executor.shutdown(timeout_sec=1.0)  # before the nodes go (rclpy's order)
        for wrapper in reversed(wrappers):
            for inputs in _inputs_of(wrapper):
                inputs.destroy()
            wrapper.node.destroy_node()
        if domain is not None:
            domain.destroy()
        rclpy.try_shutdown()
    return code


def _inputs_of(wrapper: Any) -> list[Inputs]:
    """A wrapper's ``inputs`` and, if it has them, its ``observed_inputs`` (taken in batches)."""
    return [inputs for inputs in (getattr(wrapper, "inputs", None), getattr(wrapper, "observed_inputs", None))
            if inputs is not None]


@dataclasses.dataclass(frozen=True)
class _LocalInputs:
    """Inputs on the intra-process path (queues filled by publishers of this process)."""

    hot: Sequence[tuple[deque, Callable[[bytes], None]]] = ()
    observed: Sequence[tuple[deque, Callable[[bytes], None]]] = ()
    guard: Any = None  # triggered when a message is queued from another thread


class _Group:
    """Several node wrappers seen as one: done when all are, failed if any is."""

    def __init__(self, wrappers: Sequence[Any]) -> None:
        self.wrappers = list(wrappers)
        self.stopped_by_signal: str | None = None
        periods = {getattr(w, "period", None) for w in self.wrappers} - {None}
        self.period = min(periods) if periods else None
        self.busy_wait = max((getattr(w, "busy_wait", BUSY_WAIT_S) for w in self.wrappers
                              if getattr(w, "period", None)), default=BUSY_WAIT_S)
        # real time, composed: the plant's node stays in the graph after its run, so the
        # nodes that watch for it to leave are told when it is done
        self.state_sources = [w for w in self.wrappers if getattr(w, "publishes_states", False)]
        self.watchers = [w.plant_watch for w in self.wrappers if getattr(w, "plant_watch", None)]

    @property
    def done(self) -> bool:
        for w in self.wrappers:  # checked at every pass of the loop: no generator
            if not w.done:
                return False
        return True

    @done.setter
    def done(self, value: bool) -> None:  # set by the signal handler
        for w in self.wrappers:
            w.done = value

    @property
    def exit_code(self) -> int:
        return max(w.exit_code for w in self.wrappers)

    def tick(self, lateness: float) -> None:
        for w in self.wrappers:
            if getattr(w, "period", None) and not w.done:
                w.tick(lateness)
        if self.watchers and self.state_sources and all(w.done for w in self.state_sources):
            for watch in self.watchers:
                if not watch.gone:
                    watch.gone = True
                    watch.on_gone()


COLD_PERIOD_S = 0.02  # lockstep: the executor's turn (timers, parameters, /clock) this often
# (one turn costs 0.2-1 ms of Python; every 5 ms it took 15 % of the lockstep rate)
MAX_BATCH_S = 0.05  # an observer lets its messages gather at most this long
BUSY_WAIT_S = 0.0002  # real time: default busy-wait before a tick (parameter busy_wait)
COLD_WAIT_S = 5.0  # real time: the executor thread's longest sleep (it is woken to stop)
GIL_SWITCH_S = 0.0001  # real time: longest the executor thread keeps the GIL from the loop


def _serve_loop(executor: SingleThreadedExecutor, group: Any,
                hot: Sequence[tuple[Any, Callable[[bytes], None]]], period: float | None,
                observed: Sequence[tuple[Any, Callable[[bytes], None]]] = (),
                observe_every: float = 0.0, local: _LocalInputs | None = None, *,
                busy_wait: float = BUSY_WAIT_S) -> None:
    """Take the loop's inputs with a wait set of their own; serve the rest beside them.

    Every ready input of ``hot`` is drained (``take_message`` until empty) and
    handed to its handler at every pass. Lockstep: every ``COLD_PERIOD_S`` the
    executor gets one non-blocking turn (timers, parameters, ``/clock``). Real
    time (a ``period``): the executor spins in a thread of its own instead -- one
    of its turns builds a wait set of every entity of the node and took about
    1 ms, a missed deadline each time -- and ``group.tick(lateness)`` runs on a
    wall-clock schedule: the loop sleeps in the wait set until
    ``busy_wait`` before the deadline and busy-waits the rest, because waking
    from a sleep is late by tens of microseconds, and on this machine's VM now
    and then by milliseconds (a plain Python loop that sleeps to 0.2 ms before
    each 1 kHz tick: 0.4-0.8 % of periods off by > 100 us; spinning the last
    0.8 ms: 0-2 in 5,000). Late ticks
    run at once (no burst catch-up beyond one period); ``tick`` may count missed
    deadlines from the lateness. The garbage collector is kept off the path (the
    loop creates no reference cycles) and its young generation collected now and then.

    ``observed`` are the inputs of observers (see :class:`Inputs`): once they
    have given messages, they are left alone for ``observe_every`` seconds, so
    their messages are taken in batches -- whether the observer runs alone or
    composed with the loop's nodes, whose inputs are still taken at every pass.
    ``local`` are the inputs on the intra-process path (composed
    ``--intra-process``), taken from their queues the same way; their guard
    condition wakes the loop when the real-time executor thread queues a message.
    """
    clock = time.perf_counter
    local = local or _LocalInputs()
    local_hot, local_observed = list(local.hot), list(local.observed)
    any_observed = bool(observed or local_observed)
    guard = local.guard if period else None  # only the real-time executor thread publishes off the loop
    wait_set = _rclpy_impl.WaitSet(len(hot) + len(observed), 0 if guard is None else 1, 0, 0, 0, 0,
                                   executor.context.handle)
    inputs = [(sub.handle, sub.msg_type, handler) for sub, handler in hot]
    observer_inputs = [(sub.handle, sub.msg_type, handler) for sub, handler in observed]
    gc.collect()
    gc.freeze()
    gc.disable()
    switch_interval = sys.getswitchinterval()
    if period:
        # the executor thread (timers, the recorder's flush) must hand the GIL back to the loop
        # within a fraction of a period, not after CPython's default 5 ms
        sys.setswitchinterval(GIL_SWITCH_S)
    stop = threading.Event()
    cold_thread = None
    guard_node = group.wrappers[0].node
    wake_guard = None
    if period:
        # the executor thread sleeps until it has work (timers, services); a guard condition
        # of one of its nodes ends that sleep when the loop ends (Executor.wake() does not
        # interrupt spin_once here). Waking every 0.1 s instead cost ~0.5 ms under the GIL
        # ten times a second -- a late control period each time.
        wake_guard = guard_node.create_guard_condition(lambda: None)

        def spin_cold() -> None:
            while not stop.is_set() and rclpy.ok():
                executor.spin_once(timeout_sec=COLD_WAIT_S)

        cold_thread = threading.Thread(target=spin_cold, name="executor", daemon=True)
        cold_thread.start()
    try:
        next_cold = float("inf") if period else 0.0
        next_tick = clock() + period if period else float("inf")
        next_observe = 0.0
        ok = executor.context.ok  # checked at ticks and executor turns, not at every pass
        while not group.done:
            took = _take_all(inputs)
            if local_hot and _take_local(local_hot):
                took = True
            now = clock()
            if any_observed and now >= next_observe:
                # real time: a batch must not delay the next tick; what is left waits for the
                # pass after it (next_observe unchanged)
                until = next_tick - busy_wait if period else math.inf
                observed_any = _take_batches(observer_inputs, until)
                if _take_local_batches(local_observed, until) or observed_any:
                    took = True
                    if clock() < until:
                        next_observe = now + observe_every
            if took and group.done:
                return
            now = clock()
            if now >= next_tick:
                if not ok():
                    return
                group.tick(now - next_tick)
                next_tick += period
                if now - next_tick > period:  # more than a period behind: resynchronise
                    next_tick = now + period
                continue
            if now >= next_cold:
                if not ok():
                    return
                executor.spin_once(timeout_sec=0.0)
                next_cold = now + COLD_PERIOD_S
                continue
            if gc.get_count()[0] > 50_000:
                gc.collect(0)
            if took:
                continue
            due = min(next_cold, next_tick - busy_wait, now + 0.1)
            observing = now >= next_observe
            if not observing:
                due = min(due, next_observe)
            sleep = due - now
            if sleep <= 0.0:
                continue  # busy-wait for the tick
            if _pending(local_hot) or (observing and _pending(local_observed)):
                continue
            waited = inputs + observer_inputs if observing else inputs
            if not waited and guard is None:
                if cold_thread is None and not any_observed:
                    executor.spin_once(timeout_sec=sleep)  # a node without inputs
                else:
                    time.sleep(sleep)
                continue
            wait_set.clear_entities()
            for handle, _, _ in waited:
                wait_set.add_subscription(handle)
            if guard is not None:
                wait_set.add_guard_condition(guard)
            wait_set.wait(int(sleep * 1e9))
    finally:
        stop.set()
        if wake_guard is not None:  # real time: stop the executor thread
            wake_guard.trigger()  # end its wait now
            cold_thread.join(timeout=2.0)
            if cold_thread.is_alive():
                print("warning: the executor thread did not stop within 2 s", file=sys.stderr, flush=True)
            guard_node.destroy_guard_condition(wake_guard)
        sys.setswitchinterval(switch_interval)
        gc.enable()
        gc.unfreeze()


def _take_all(inputs: Sequence[tuple[Any, Any, Callable[[bytes], None]]]) -> bool:
    """Hand every waiting message of ``inputs`` to its handler; whether there was any."""
    took = False
    for handle, msg_type, handler in inputs:
        while True:
            taken = handle.take_message(msg_type, True)
            if taken is None:
                break
            handler(taken[0])
            took = True
    return took


def _take_local(inputs: Sequence[tuple[deque, Callable[[bytes], None]]]) -> bool:
    """:func:`_take_all` for intra-process inputs: empty each queue into its handler."""
    took = False
    for queue, handler in inputs:
        while queue:
            handler(queue.popleft())
            took = True
    return took


BOUNDED_BATCH = 8  # real time: an observer's batch handed over while a tick is near


def _take_batches(inputs: Sequence[tuple[Any, Any, Callable[[list[bytes]], None]]],
                  until: float = math.inf) -> bool:
    """Observers: each input's waiting messages to its handler as one list.

    Once ``time.perf_counter()`` reaches ``until`` (a real-time tick is near),
    at most ``BOUNDED_BATCH`` messages per input, and none after the first
    input that had some; the rest stay queued for the next pass.
    """
    took = False
    for handle, msg_type, handler in inputs:
        limit = BOUNDED_BATCH if time.perf_counter() >= until else -1
        batch = []
        while len(batch) != limit:
            taken = handle.take_message(msg_type, True)
            if taken is None:
                break
            batch.append(taken[0])
        if batch:
            handler(batch)
            took = True
            if limit > 0:
                return took
    return took


def _take_local_batches(inputs: Sequence[tuple[deque, Callable[[list[bytes]], None]]],
                        until: float = math.inf) -> bool:
    """:func:`_take_batches` for intra-process inputs."""
    took = False
    for queue, handler in inputs:
        count = len(queue)
        if not count:
            continue
        bounded = time.perf_counter() >= until
        if bounded:
            count = min(count, BOUNDED_BATCH)
        # popleft, not a copy and clear(): the real-time executor thread may append meanwhile
        handler([queue.popleft() for _ in range(count)])
        took = True
        if bounded:
            return took
    return took


def _pending(inputs: Sequence[tuple[deque, Callable[[bytes], None]]]) -> bool:
    return any(queue for queue, _ in inputs)


def _drain(executor: Any, wrappers: Sequence[Any], timeout: float = DRAIN_TIMEOUT_S) -> None:
    """After the work is done: let subscribers acknowledge the last messages, then linger.

    A reliable sample lost on the way is repaired only after the writer's next
    heartbeat; a node that exits at once never repairs it (a real-time
    trajectory once missed the plant's last state this way). Waits at most
    ``timeout`` in all (a killed subscriber never acknowledges), then serves
    the executor briefly for what needs a callback (parameter events, acks).
    """
    end = time.perf_counter() + timeout
    for wrapper in wrappers:
        for publisher in wrapper.node.publishers:
            left = end - time.perf_counter()
            if left <= 0.0:
                break
            publisher.wait_for_all_acked(Duration(nanoseconds=int(left * 1e9)))
    end = time.perf_counter() + 0.1
    while rclpy.ok() and time.perf_counter() < end:
        executor.spin_once(timeout_sec=0.02)


class _SignalNote:
    """Where a signal that arrives before the node group exists is noted."""

    done = False
    stopped_by_signal: str | None = None


def _install_signal_handlers(wrapper: Any) -> None:
    """SIGINT/SIGTERM end the spin loop; the node's close() then runs."""

    def handler(signum: int, frame: object) -> None:  # noqa: ARG001
        wrapper.done = True
        wrapper.stopped_by_signal = signal.Signals(signum).name

    signal.signal(signal.SIGINT, handler)
    signal.signal(signal.SIGTERM, handler)
