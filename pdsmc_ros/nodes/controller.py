"""Controller node: PD, SMC or PD-SMC, selected with ``-p type:=pd|smc|pdsmc``.

A managed (lifecycle) node that configures and activates itself unless
``autostart:=false``. Subscribes to ``/joint_states`` (``sensor_msgs/JointState``)
and to two reference sources -- ``/reference`` (this package's one-point-per-step
stream) and ``~/joint_trajectory`` (``trajectory_msgs/JointTrajectory``, as
joint_trajectory_controller's topic interface); whichever spoke last drives
the controller. Joints are matched by name (parameter ``joints``): any order,
extra joints ignored. Publishes ``std_msgs/Float64MultiArray`` torques on
``/effort_controller/commands`` like ros2_control's forward command
controller (``data[i]`` for ``joints[i]``; ``layout.data_offset`` carries the
control step in lockstep and is 0 in real time), the run description (JSON,
latched) on ``/pdsmc/run_description`` and input problems on ``/diagnostics``.
The law itself is :class:`pdsmc_ros.simulator.ControlLaw`.

Lockstep: the torque of step ``k`` is computed once the state and the
reference of step ``k`` are both in (stamps are sim time, ``k / rate``).
Real time: at the control rate, with the latest state and reference; stamps
are whatever the source sends and are never read as a step. When the
controller stops commanding (SIGINT/SIGTERM, lifecycle deactivate or
shutdown, inputs stale in real time) it publishes one zero-effort command
first: a forward command controller holds the last command forever.
"""

from __future__ import annotations

import math
import sys
import threading
import time
from collections.abc import Sequence

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rcl_interfaces.msg import ParameterDescriptor
from rclpy.duration import Duration
from rclpy.lifecycle import (
    LifecycleNode,
    LifecycleState,
    ManagedEntity,
    TransitionCallbackReturn,
)
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray, MultiArrayDimension, String
from trajectory_msgs.msg import JointTrajectory

from ..bag.cdr import (
    decode_joint_state_named,
    decode_joint_trajectory_named,
    decode_joint_trajectory_points,
    encode_float64_multi_array,
)
from ..bag.stamps import stamp_step
from ..errors import CdrError, ConfigError
from ..joint_trajectory import JointTrajectoryReference
from ..joints import JointSelector, check_joint_names
from ..presets import Gains, RunSpec
from ..safety import Staleness, limit_torque
from ..simulator import ControlLaw, control_steps
from ..stability import check_rate
from .executor import run_node
from .io import GuardedPublisher, Inputs
from .lifecycle import EXIT_OK, end_when_plant_leaves
from .params import (
    GainUpdates,
    declare_busy_wait,
    declare_int_parameter,
    declare_run_parameters,
    description_json,
    run_spec_from_parameters,
    torque_limit_from_parameters,
)
from .topics import (
    LATCHED_QOS,
    STREAM_QOS,
    TOPIC_DESCRIPTION,
    TOPIC_DIAGNOSTICS,
    TOPIC_EFFORT,
    TOPIC_JOINT_STATES,
    TOPIC_JOINT_TRAJECTORY,
    TOPIC_REFERENCE,
    TOPIC_TIMING,
    TRAJECTORY_QOS,
)

# Real time: achieved-period rows [wall time, period, compute time, lateness, missed so far]
# go out in batches (one publish costs about as much as the control law's whole tick)
TIMING_FIELDS = 5
TIMING_BATCH = 50
MAX_STEP = 2**32 - 1  # layout.data_offset is a uint32
ERROR_THROTTLE_S = 1.0  # one log line per second for a repeated input error
GOAL_BATCH_S = 0.002  # ~/joint_trajectory is looked at every 2 ms
STOP_ACK_S = 0.5  # how long a stopping controller waits for its zero command to be acknowledged


class ControllerNode(ManagedEntity):
    """Thin wrapper around :class:`~pdsmc_ros.simulator.ControlLaw` (a lifecycle node's entity)."""

    def __init__(self) -> None:
        self.node = LifecycleNode("controller")
        node = self.node
        declare_run_parameters(node, gains=True)
        self.busy_wait = declare_busy_wait(node)  # used in real time
        node.declare_parameter("torque_limit", None, ParameterDescriptor(
            description="optional per-joint torque limits in N m (empty: none)", dynamic_typing=True))
        self.stale_periods = declare_int_parameter(
            node, "stale_periods", 20, "real time: periods after which a state or reference is stale",
            lo=1, hi=1_000_000)
        self.spec = run_spec_from_parameters(node)
        robot = self.spec.robot_model()
        node.declare_parameter("joints", list(robot.joint_names), ParameterDescriptor(
            description="controlled joints, in the order of the commands' data (default: the robot's "
                        "actuated joints); states and trajectories are matched by these names",
            dynamic_typing=True))
        node.declare_parameter("autostart", True, ParameterDescriptor(
            description="configure and activate at start (false: wait for the lifecycle transitions)"))
        self.joints = check_joint_names(node.get_parameter("joints").value, robot.n)
        self.selector = JointSelector(self.joints)
        autostart = node.get_parameter("autostart").value
        if not isinstance(autostart, bool):
            raise ConfigError(f"parameter autostart must be true or false, got {autostart!r}")
        self.torque_limit = torque_limit_from_parameters(node, len(self.spec.gains.kp))
        self.mode = node.get_parameter("mode").value
        self.lockstep = self.mode == "lockstep"
        self.reference = self.spec.reference()
        check_rate(self.spec, self.reference)  # refuse gains unstable at this rate
        self.gain_updates = GainUpdates(node, self.spec, self.check_gains, self.apply_gains)
        self.n = robot.n
        self.last_step = control_steps(self.spec.contour_model().duration, self.spec.rate)
        self.law: ControlLaw | None = None
        self.active = False
        self.commanding = False  # a non-zero command may be the last one on the wire
        # real time: lifecycle transitions run in the executor's thread; no torque may follow
        # the zero command of a deactivation
        self.command_lock = threading.Lock()
        self.non_finite = 0
        self.clamped = 0
        self.input_error: str | None = None  # the current problem with the inputs, if any
        self.states_received = 0
        # lockstep: the state of the step being computed; real time: the latest state
        self.state: tuple[int, np.ndarray, np.ndarray] | None = None
        self.last_state: tuple[int, np.ndarray, np.ndarray] | None = None  # for trajectories
        self.refs: dict[int, tuple[np.ndarray, np.ndarray, np.ndarray]] = {}
        self.latest_ref: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
        self.trajectory: JointTrajectoryReference | None = None
        self.source: str | None = None  # "reference" or "trajectory": whichever spoke last
        self.next_offset = 0  # lockstep: the step a stop command is for
        self.done = False
        self.finished = False  # lockstep: the effort of the last step went out
        self.exit_code = EXIT_OK
        self.last_tick: float | None = None
        self.state_time = 0.0
        self.ref_time = 0.0

        self.pub_effort = GuardedPublisher(node.create_publisher(Float64MultiArray, TOPIC_EFFORT, STREAM_QOS), node)
        self.pub_desc = node.create_publisher(String, TOPIC_DESCRIPTION, LATCHED_QOS)
        self.pub_timing = GuardedPublisher(node.create_publisher(Float64MultiArray, TOPIC_TIMING, STREAM_QOS), node)
        self.pub_diag = GuardedPublisher(node.create_publisher(DiagnosticArray, TOPIC_DIAGNOSTICS, STREAM_QOS), node)
        self.inputs = Inputs(node, self.mode)
        self.inputs.subscribe(JointState, TOPIC_JOINT_STATES, self.on_state)
        self.inputs.subscribe(JointTrajectory, TOPIC_REFERENCE, self.on_reference)
        # off the loop's path: a goal is rare, and an input taken at every pass of the loop costs
        # a take per pass even when empty (about a tenth of the lockstep rate)
        self.observed_inputs = Inputs(node, self.mode, batch_s=GOAL_BATCH_S, suffix="_goals")
        self.observed_inputs.subscribe(JointTrajectory, TOPIC_JOINT_TRAJECTORY, self.on_joint_trajectories,
                                       TRAJECTORY_QOS)
        self.pub_desc.publish(String(data=description_json(self.spec, self.mode)))
        if self.mode == "realtime":
            self.period = 1.0 / self.spec.rate  # run_node paces tick() at this period
            self.staleness = Staleness(self.stale_periods * self.period)
            self.missed = 0
            self.timing_rows: list[float] = []
            self.plant_watch = end_when_plant_leaves(self, lambda: self.states_received)
        node.add_managed_entity(self)
        if autostart:
            node.trigger_configure()
            node.trigger_activate()
        node.get_logger().info(
            f"{self.spec.controller} controller for {self.spec.robot}/{self.spec.contour}, "
            f"{self.mode}, {self.spec.rate:g} Hz, joints {list(self.joints)}"
            + ("" if autostart else "; unconfigured until configure and activate"))

    # -- lifecycle ------------------------------------------------------------ #
    def on_configure(self, state: LifecycleState) -> TransitionCallbackReturn:  # noqa: ARG002
        law = ControlLaw(self.spec)
        start = self.reference.sample([0.0])
        law.warm_up(start.q[0], start.qd[0])  # not on the first tick (numba loads it)
        self.law = law
        return TransitionCallbackReturn.SUCCESS

    def on_activate(self, state: LifecycleState) -> TransitionCallbackReturn:  # noqa: ARG002
        self.active = True
        self.node.get_logger().info("active: commanding")
        return TransitionCallbackReturn.SUCCESS

    def on_deactivate(self, state: LifecycleState) -> TransitionCallbackReturn:  # noqa: ARG002
        with self.command_lock:
            self.active = False
        self.stop_commanding("deactivated")
        return TransitionCallbackReturn.SUCCESS

    def on_cleanup(self, state: LifecycleState) -> TransitionCallbackReturn:  # noqa: ARG002
        self.law = None
        return TransitionCallbackReturn.SUCCESS

    def on_shutdown(self, state: LifecycleState) -> TransitionCallbackReturn:  # noqa: ARG002
        self.active = False
        self.stop_commanding("shut down")
        self.done = True
        return TransitionCallbackReturn.SUCCESS

    def on_error(self, state: LifecycleState) -> TransitionCallbackReturn:  # noqa: ARG002
        self.active = False
        self.stop_commanding("lifecycle error")
        return TransitionCallbackReturn.SUCCESS

    # -- gains ---------------------------------------------------------------- #
    def check_gains(self, spec: RunSpec) -> None:
        """The start-up checks of a gain change (on-set): stable at the running rate."""
        check_rate(spec, self.reference)

    def apply_gains(self, gains: Gains) -> None:
        """An accepted gain change (post-set): a new law, swapped in whole between ticks."""
        self.spec = self.gain_updates.spec
        if self.law is not None:
            self.law = ControlLaw(self.spec)  # one attribute store: a tick uses the old or the new
        self.node.get_logger().info(f"gains changed: {gains.as_dict()}")

    # -- inputs --------------------------------------------------------------- #
    def report_input(self, problem: str | None) -> None:
        """A problem with the inputs (throttled error, diagnostic) or its end (recovered)."""
        logger = self.node.get_logger()
        if problem is None:
            if self.input_error is not None:
                logger.info("complete inputs again: control resumed")
                self.diagnose(DiagnosticStatus.OK, "inputs complete")
                self.input_error = None
            return
        if problem != self.input_error:
            self.diagnose(DiagnosticStatus.ERROR, problem)
        self.input_error = problem
        logger.error(f"{problem}: no torque computed from it", throttle_duration_sec=ERROR_THROTTLE_S)

    def diagnose(self, level: bytes, text: str) -> None:
        msg = DiagnosticArray()
        msg.header.stamp = self.node.get_clock().now().to_msg()
        msg.status = [DiagnosticStatus(level=level, name="controller: inputs", message=text,
                                       hardware_id=self.spec.robot,
                                       values=[KeyValue(key="joints", value=",".join(self.joints))])]
        self.pub_diag.publish(msg)

    def on_state(self, data: bytes) -> None:
        try:
            names, sec, nanosec, position, velocity, _ = decode_joint_state_named(data)
        except CdrError as exc:
            self.report_input(f"malformed /joint_states message ({exc})")
            return
        arrays, problem = self.selector.state(names, position, velocity)
        if problem:
            self.report_input(f"/joint_states: {problem}")
            if self.mode == "realtime":
                self.state = None  # no torque from an older state meanwhile
            return
        if self.lockstep:
            step = stamp_step(sec, nanosec, self.spec.rate)
            if not 0 <= step <= MAX_STEP:
                self.report_input(f"/joint_states stamp {sec}.{nanosec:09d} s is not a lockstep step "
                                  "(lockstep needs the plant's sim time; use mode:=realtime)")
                return
        else:
            step = -1  # real time: stamps are the source's; no step is read from them
        q, qd = arrays
        if self.input_error is not None:
            self.report_input(None)
        self.states_received += 1
        self.state = self.last_state = (step, q, qd)
        if self.lockstep:
            self.try_compute()
        else:
            self.state_time = time.perf_counter()

    def on_reference(self, data: bytes) -> None:
        try:
            decoded = decode_joint_trajectory_named(data)
        except CdrError as exc:
            self.report_input(f"malformed /reference message ({exc})")
            return
        if decoded is None:
            return
        names, sec, nanosec, positions, velocities, accelerations = decoded
        arrays, problem = self.selector.reference(names, positions, velocities, accelerations)
        if problem:
            self.report_input(f"/reference: {problem}")
            return
        self.source = "reference"
        if self.lockstep:
            step = stamp_step(sec, nanosec, self.spec.rate)
            if 0 <= step <= MAX_STEP:
                self.refs[step] = arrays
                self.try_compute()
        else:
            self.latest_ref = arrays
            self.ref_time = time.perf_counter()

    def now(self) -> float:
        """The controller's time in seconds: the lockstep state's sim time, else the node's clock."""
        if self.lockstep:
            return (self.last_state[0] if self.last_state is not None else 0) / self.spec.rate
        return self.node.get_clock().now().nanoseconds * 1e-9

    def on_joint_trajectories(self, batch: list[bytes]) -> None:
        """Goals taken in a batch: each replaces the previous one, in order."""
        for data in batch:
            self.on_joint_trajectory(data)

    def on_joint_trajectory(self, data: bytes) -> None:
        topic = self.node.resolve_topic_name(TOPIC_JOINT_TRAJECTORY)
        try:
            sec, nanosec, names, points = decode_joint_trajectory_points(data)
        except CdrError as exc:
            self.node.get_logger().error(f"malformed {topic} message refused ({exc})")
            return
        if self.last_state is None:
            self.node.get_logger().error(
                f"{topic}: trajectory refused: no complete joint state yet (the motion starts from it)")
            return
        _, q, qd = self.last_state
        reference, problem = JointTrajectoryReference.from_message(
            self.selector, sec + nanosec * 1e-9, names, points, self.now(), q, qd)
        if reference is None:
            self.node.get_logger().error(f"{topic}: trajectory refused: {problem}")
            return
        self.trajectory = reference
        self.source = "trajectory"
        self.node.get_logger().info(
            f"{topic}: {len(points)} points until t = {reference.end_time:.3f} s; driving from it")
        if self.lockstep:
            self.try_compute()

    # -- control -------------------------------------------------------------- #
    def try_compute(self) -> None:
        """Lockstep: the torque of the pending state once its reference is in."""
        if self.state is None:
            return
        step, q, qd = self.state
        if self.source == "trajectory":
            ref = self.trajectory.sample(step / self.spec.rate)
            self.refs.pop(step, None)
        else:
            ref = self.refs.pop(step, None)
            if ref is None:
                return
        # references of states that will not come (safe mode): they arrived in step order,
        # so they are the oldest entries (the trajectory sends references ahead)
        while self.refs:
            oldest = next(iter(self.refs))
            if oldest >= step:
                break
            del self.refs[oldest]
        self.state = None
        self.next_offset = step + 1
        law = self.law
        if self.active and law is not None:
            self.publish(law.torque(q, qd, *ref), step)
        if step >= self.last_step:
            self.finished = self.done = True

    def publish(self, tau: np.ndarray, step: int) -> None:
        """Publish a torque -- never a non-finite one; clamp to the limits if set."""
        values = tau.tolist()
        if not all(map(math.isfinite, values)):
            self.non_finite += 1
            if self.non_finite <= 5 or self.non_finite % 1000 == 0:
                self.node.get_logger().error(
                    f"non-finite torque {values} not published ({self.non_finite} so far)")
            return
        if self.torque_limit is not None:
            tau, clamped = limit_torque(tau, self.torque_limit)
            if clamped:
                values = tau.tolist()
                self.clamped += 1
                if self.clamped <= 5 or self.clamped % 1000 == 0:
                    self.node.get_logger().warn(f"torque limited ({self.clamped} so far)")
        self.pub_effort.publish(encode_float64_multi_array(values, step))
        self.commanding = True

    def stop_commanding(self, why: str) -> bool:
        """Publish one zero-effort command if the last one on the wire may be a torque
        (whether it did)."""
        with self.command_lock:
            if not self.commanding:
                return False
            offset = min(self.next_offset, MAX_STEP) if self.lockstep else 0
            self.pub_effort.publish(encode_float64_multi_array([0.0] * self.n, offset))
            self.commanding = False
        self.node.get_logger().warn(f"{why}: zero effort published, output stopped")
        return True

    def tick(self, lateness: float) -> None:
        """Real time: one control period, then (rarely) a look at whether the plant is there."""
        self.control(lateness)
        self.plant_watch.poll()

    def control(self, lateness: float) -> None:
        """Real time: torque from the latest state and reference; timing recorded.

        Publishes ``[wall time (s), achieved period (s), compute time (s),
        lateness (s), missed deadlines so far]`` rows on ``/pdsmc/controller_timing``,
        ``TIMING_BATCH`` rows per message.
        """
        now = time.perf_counter()
        if lateness > self.period:
            self.missed += 1
        law, state, source = self.law, self.state, self.source
        if not self.active or law is None or source is None or self.states_received == 0:
            self.last_tick = now
            return
        change = self.staleness.update(now, self.state_time, self.ref_time if source == "reference" else None)
        if change == "stale":
            self.node.get_logger().error(f"state or reference older than {self.stale_periods} periods")
            self.stop_commanding("inputs stale")
        elif change == "fresh":
            self.node.get_logger().info("fresh state and reference again: output resumed")
        if self.staleness.stale:
            self.last_tick = now
            return
        if state is None:  # the latest state was incomplete: reported by on_state
            self.last_tick = now
            return
        _, q, qd = state
        ref = self.latest_ref if source == "reference" else self.trajectory.sample(self.now())
        tau = law.torque(q, qd, *ref)
        with self.command_lock:
            if self.active:
                self.publish(tau, 0)
        period = 0.0 if self.last_tick is None else now - self.last_tick
        self.last_tick = now
        self.timing_rows += [time.time(), period, time.perf_counter() - now, lateness, float(self.missed)]
        if len(self.timing_rows) >= TIMING_FIELDS * TIMING_BATCH:
            self.publish_timing()

    def publish_timing(self) -> None:
        """Publish the pending timing rows as one ``rows x 5`` Float64MultiArray."""
        if not self.timing_rows:
            return
        rows = len(self.timing_rows) // TIMING_FIELDS
        msg = Float64MultiArray()
        msg.layout.dim = [
            MultiArrayDimension(label="tick", size=rows, stride=rows * TIMING_FIELDS),
            MultiArrayDimension(label="field", size=TIMING_FIELDS, stride=TIMING_FIELDS),
        ]
        msg.data = self.timing_rows
        self.pub_timing.publish(msg)
        self.timing_rows = []

    def close(self) -> None:
        """Stopping (signal, end of run): a zero command unless the lockstep run is complete."""
        if self.mode == "realtime":
            self.publish_timing()
        # a complete lockstep run: the plant has its last effort and has ended
        if not self.finished and self.stop_commanding("stopping"):
            self.pub_effort.publisher.wait_for_all_acked(Duration(nanoseconds=int(STOP_ACK_S * 1e9)))


def main(args: Sequence[str] | None = None) -> int:
    return run_node("controller", ControllerNode, args)


if __name__ == "__main__":
    sys.exit(main())
