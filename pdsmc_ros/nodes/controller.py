"""Controller node: PD, SMC or PD-SMC, selected with ``-p type:=pd|smc|pdsmc``.

Subscribes to ``/joint_states`` and ``/reference`` and publishes
``std_msgs/Float64MultiArray`` torques on ``/effort_controller/commands`` like
ros2_control's forward command controller (``layout.data_offset`` carries the
control step in lockstep mode). It also publishes the run description
(JSON, latched) on ``/pdsmc/run_description``. The law itself is
:class:`pdsmc_ros.simulator.ControlLaw`.

Lockstep: the torque of step ``k`` is computed once the state and the
reference of step ``k`` are both in. Real time: a wall-clock timer computes
with the latest state and reference and publishes the achieved period on
``/pdsmc/controller_timing``.
"""

from __future__ import annotations

import dataclasses
import math
import sys
import time
from collections.abc import Sequence

import numpy as np
from rcl_interfaces.msg import ParameterDescriptor
from rclpy.node import Node
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray, MultiArrayDimension, String
from trajectory_msgs.msg import JointTrajectory

from ..cdr import decode_joint_state, decode_joint_trajectory, encode_float64_multi_array
from ..presets import Gains
from ..safety import limit_torque
from ..simulator import ControlLaw, control_steps
from ..stability import check_rate
from .common import (
    GuardedPublisher,
    Inputs,
    EXIT_OK,
    LATCHED_QOS,
    STREAM_QOS,
    TOPIC_DESCRIPTION,
    TOPIC_EFFORT,
    TOPIC_JOINT_STATES,
    TOPIC_REFERENCE,
    TOPIC_TIMING,
    declare_busy_wait,
    declare_int_parameter,
    declare_run_parameters,
    description_json,
    end_when_plant_leaves,
    gains_callback,
    run_node,
    run_spec_from_parameters,
    stamp_to_step,
    torque_limit_from_parameters,
)


# Real time: achieved-period rows [wall time, period, compute time, lateness, missed so far]
# go out in batches (one publish costs about as much as the control law's whole tick)
TIMING_FIELDS = 5
TIMING_BATCH = 50


class ControllerNode:
    """Thin wrapper around :class:`~pdsmc_ros.simulator.ControlLaw`."""

    def __init__(self) -> None:
        self.node = Node("controller")
        node = self.node
        declare_run_parameters(node, gains=True)
        self.busy_wait = declare_busy_wait(node)  # used in real time
        node.declare_parameter("torque_limit", None, ParameterDescriptor(
            description="optional per-joint torque limits in N m (empty: none)", dynamic_typing=True))
        self.stale_periods = declare_int_parameter(
            node, "stale_periods", 20, "real time: periods after which a state or reference is stale",
            lo=1, hi=1_000_000)
        self.spec = run_spec_from_parameters(node)
        self.torque_limit = torque_limit_from_parameters(node, len(self.spec.gains.kp))
        self.non_finite = 0
        self.clamped = 0
        self.stale = False
        node.add_on_set_parameters_callback(gains_callback(self.spec, self.apply_gains))
        self.mode = node.get_parameter("mode").value
        reference = self.spec.reference()
        check_rate(self.spec, reference)  # refuse gains unstable at this rate
        self.law = ControlLaw(self.spec)
        start = reference.sample([0.0])
        self.law.warm_up(start.q[0], start.qd[0])  # not on the first tick (numba loads it)
        self.n = self.law.n
        self.last_step = control_steps(self.spec.contour_model().duration, self.spec.rate)
        self.state: tuple[int, np.ndarray, np.ndarray] | None = None
        self.refs: dict[int, tuple[np.ndarray, np.ndarray, np.ndarray]] = {}
        self.latest_ref: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
        self.done = False
        self.exit_code = EXIT_OK
        self.last_tick: float | None = None
        self.state_time = 0.0
        self.ref_time = 0.0

        self.pub_effort = GuardedPublisher(node.create_publisher(Float64MultiArray, TOPIC_EFFORT, STREAM_QOS), node)
        self.pub_desc = node.create_publisher(String, TOPIC_DESCRIPTION, LATCHED_QOS)
        self.pub_timing = GuardedPublisher(node.create_publisher(Float64MultiArray, TOPIC_TIMING, STREAM_QOS), node)
        self.inputs = Inputs(node, self.mode)
        self.inputs.subscribe(JointState, TOPIC_JOINT_STATES, self.on_state)
        self.inputs.subscribe(JointTrajectory, TOPIC_REFERENCE, self.on_reference)
        self.pub_desc.publish(String(data=description_json(self.spec, self.mode)))
        if self.mode == "realtime":
            self.period = 1.0 / self.spec.rate  # run_node paces tick() at this period
            self.missed = 0
            self.deadline: float | None = None
            self.timing_rows: list[float] = []
            self.plant_watch = end_when_plant_leaves(
                self, lambda: self.state[0] if self.state is not None else -1)
        node.get_logger().info(
            f"{self.spec.controller} controller for {self.spec.robot}/{self.spec.contour}, "
            f"{self.mode}, {self.spec.rate:g} Hz"
        )

    def apply_gains(self, gains: Gains) -> None:
        """Validated run-time gain change (set-parameters callback)."""
        self.spec = dataclasses.replace(self.spec, gains=gains)
        self.law = ControlLaw(self.spec)
        self.node.get_logger().info(f"gains changed: {gains.as_dict()}")

    def on_state(self, data: bytes) -> None:
        sec, nanosec, position, velocity, _ = decode_joint_state(data)
        if len(position) < self.n or len(velocity) < self.n:
            return  # not this arm's state (the plant always sends every joint)
        step = stamp_to_step(sec, nanosec, self.spec.rate)
        q = np.array(position[: self.n])
        qd = np.array(velocity[: self.n])
        self.state = (step, q, qd)
        self.state_time = time.perf_counter()
        if self.mode == "lockstep":
            self.try_compute()

    def on_reference(self, data: bytes) -> None:
        decoded = decode_joint_trajectory(data)
        if decoded is None:
            return
        sec, nanosec, positions, velocities, accelerations = decoded
        if not len(positions) == len(velocities) == len(accelerations) == self.n:
            return  # not this arm's reference
        ref = (np.array(positions), np.array(velocities), np.array(accelerations))
        self.latest_ref = ref
        self.ref_time = time.perf_counter()
        if self.mode == "lockstep":
            step = stamp_to_step(sec, nanosec, self.spec.rate)
            self.refs[step] = ref
            self.try_compute()

    def try_compute(self) -> None:
        if self.state is None:
            return
        step, q, qd = self.state
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
        self.publish(self.law.torque(q, qd, *ref), step)
        self.state = None
        if step >= self.last_step:
            self.done = True

    def publish(self, tau: np.ndarray, step: int) -> None:
        """Publish a torque -- never a non-finite one; clamp to the limits if set."""
        values = tau.tolist()
        if not all(map(math.isfinite, values)):
            self.non_finite += 1
            if self.non_finite <= 5 or self.non_finite % 1000 == 0:
                self.node.get_logger().error(
                    f"non-finite torque {values} at step {step} not published "
                    f"({self.non_finite} so far)")
            return
        if self.torque_limit is not None:
            tau, clamped = limit_torque(tau, self.torque_limit)
            if clamped:
                values = tau.tolist()
                self.clamped += 1
                if self.clamped <= 5 or self.clamped % 1000 == 0:
                    self.node.get_logger().warn(f"torque limited at step {step} ({self.clamped} so far)")
        self.pub_effort.publish(encode_float64_multi_array(values, step))

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
        if self.state is None or self.latest_ref is None:
            self.last_tick = now
            return
        if self.deadline is None:
            # the plant's clock runs at wall speed: the run is over a few seconds after T
            self.deadline = now + self.last_step / self.spec.rate + 5.0
        elif now > self.deadline:
            self.done = True
        step, q, qd = self.state
        stale = now - self.state_time > self.stale_periods * self.period or \
            now - self.ref_time > self.stale_periods * self.period
        if stale:
            if not self.stale:
                self.node.get_logger().error(
                    f"state or reference older than {self.stale_periods} periods: output stopped")
            self.stale = True
            self.last_tick = now
            return
        if self.stale:
            self.node.get_logger().info("fresh state and reference again: output resumed")
            self.stale = False
        self.publish(self.law.torque(q, qd, *self.latest_ref), step)
        period = 0.0 if self.last_tick is None else now - self.last_tick
        self.last_tick = now
        self.timing_rows += [time.time(), period, time.perf_counter() - now, lateness, float(self.missed)]
        if len(self.timing_rows) >= TIMING_FIELDS * TIMING_BATCH:
            self.publish_timing()
        if step >= self.last_step:
            self.done = True
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
        if self.mode == "realtime":
            self.publish_timing()


def main(args: Sequence[str] | None = None) -> int:
    return run_node("controller", ControllerNode, args)


if __name__ == "__main__":
    sys.exit(main())
