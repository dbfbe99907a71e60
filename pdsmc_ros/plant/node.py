"""Plant simulator node: integrates Eq. (4.1) one control period per effort command.

Publishes ``/joint_states`` every control step (position, velocity and, in
``effort``, the torque applied over the period that ended at the stamp; passive
joints of the five-bar too), the actual end-effector point at the statistics
rate, and in lockstep mode ``/clock`` at ``clock_rate`` (default 100 Hz of sim
time, ten times gazebo_ros's default: the nodes' own timing needs no sim clock,
and each /clock message fans out to every node's time source -- at 1 kHz that
was about 13 % of a composed lockstep step).

Lockstep: state ``k`` is published, the plant waits for the effort of step
``k`` (``layout.data_offset == k``), integrates one period with it held and
publishes state ``k + 1``. Real time: a wall-clock timer integrates with the
latest effort at the control rate.

Limits (issue 29): the applied torque is clamped to the arm's effort limits (a drive
saturates; ``enforce_limits:=false`` opts out), the first crossing of each joint's position and
velocity limit is a warning, and a diverged state (not finite, or beyond the bounds of
:class:`~pdsmc_ros.sim.divergence.DivergenceCheck`) ends the node with an error and exit status 1.

``/robot_description`` (``std_msgs/String``, transient local, as
robot_state_publisher publishes it): the URDF of the arm, generated from
``config/robots.yaml`` (:mod:`pdsmc_ros.robots.urdf`: the arms in the x-z plane, z up).
"""

from __future__ import annotations

import sys
import time
from collections.abc import Sequence

import numpy as np
from builtin_interfaces.msg import Time
from geometry_msgs.msg import PointStamped
from rclpy.node import Node
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray, String

from ..bag.cdr import decode_float64_multi_array, encode_clock, encode_joint_state, encode_point_stamped
from ..bag.stamps import step_stamp
from ..errors import CdrError
from ..loop.inputs import Inputs
from ..loop.lifecycle import EXIT_FAILURE, EXIT_OK
from ..loop.process import run_node
from ..parameters.descriptors import decimation
from ..parameters.tables import PLANT_PRIORITY
from ..ros.diagnostics import Diagnostics
from ..ros.node_run import declare_node_run
from ..ros.publishers import GuardedPublisher
from ..ros.topics import (
    LATCHED_QOS,
    LATEST_QOS,
    STEADY_CLOCK,
    STREAM_QOS,
    THROTTLE_RATE,
    TOPIC_EE_ACTUAL,
    TOPIC_EFFORT,
    TOPIC_JOINT_STATES,
    TOPIC_JOINT_STATES_THROTTLED,
    TOPIC_ROBOT_DESCRIPTION,
)
from ..runs.builder import control_steps
from ..sim.plant import PlantStepper
from ..sim.supervised import SupervisedPlant
from .parameters import declare_plant_parameters


class PlantNode:
    """Thin wrapper: parameters, QoS and topics around :class:`SupervisedPlant`."""

    publishes_states = True  # composed in real time: its end is the end of the states
    realtime_priority = PLANT_PRIORITY  # thread_priority's default in real time: below the controller's

    def __init__(self) -> None:
        self.node = node = Node("plant")
        run = declare_node_run(node)
        self.spec = spec = run.spec
        self.mode, self.busy_wait = run.mode, run.busy_wait
        params = declare_plant_parameters(node, spec.rate)
        self.expected = params.expected_subscribers
        reference = spec.reference()
        robot = spec.robot_model()
        stepper = PlantStepper(robot, 1.0 / spec.rate, reference.sample([0.0]).q[0], np.zeros(robot.n))
        stepper.warm_up()  # not on the first step (numba loads the kernel)
        self.stepper = stepper
        self.names = list(robot.joint_names) + list(robot.passive_joint_names)
        self.n_passive = len(robot.passive_joint_names)
        self.clock_every = decimation(spec.rate, node.get_parameter("clock_rate").value)
        self.ee_every = spec.sample_every
        self.throttle_every = decimation(spec.rate, THROTTLE_RATE)

        self.pub_state = GuardedPublisher(node.create_publisher(JointState, TOPIC_JOINT_STATES, STREAM_QOS), node)
        self.pub_ee = GuardedPublisher(node.create_publisher(PointStamped, TOPIC_EE_ACTUAL, STREAM_QOS), node)
        self.pub_throttled = GuardedPublisher(
            node.create_publisher(JointState, TOPIC_JOINT_STATES_THROTTLED, LATEST_QOS), node)
        self.pub_clock = GuardedPublisher(node.create_publisher(Clock, "/clock", STREAM_QOS), node)
        self.pub_urdf = node.create_publisher(String, TOPIC_ROBOT_DESCRIPTION, LATCHED_QOS)
        self.pub_urdf.publish(String(data=spec.robot_description()))
        self.diagnostics = Diagnostics(node, "pdsmc_ros/plant", spec.robot, values=self.status,
                                       stamp=lambda: Time(sec=self.stamp()[0], nanosec=self.stamp()[1]))
        self.plant = SupervisedPlant(
            stepper, last_step=control_steps(reference.duration, spec.rate), watchdog=params.watchdog,
            safety=params.safety, lockstep=self.mode == "lockstep", publish_state=self.publish_state,
            report=self.diagnostics.report, limit=robot.effort_limits if params.enforce_limits else None)
        self.inputs = Inputs(node, self.mode)
        self.inputs.subscribe(Float64MultiArray, TOPIC_EFFORT, self.on_effort)

        if self.mode == "lockstep":
            self.timer = node.create_timer(0.01, self.try_start, clock=STEADY_CLOCK)
            self.watchdog = node.create_timer(0.01, lambda: self.plant.check_watchdog(time.monotonic()),
                                              clock=STEADY_CLOCK)
        else:
            self.period = 1.0 / spec.rate  # run_node paces tick() at this period
        node.get_logger().info(f"{spec.robot} plant, {self.mode}, {spec.rate:g} Hz, {self.plant.last_step} steps, "
                               f"payload {spec.payload:g} kg")

    @property
    def exit_code(self) -> int:
        """1 once the arm diverged (the error is in the log and on /diagnostics)."""
        return EXIT_FAILURE if self.plant.failure else EXIT_OK

    @property
    def done(self) -> bool:
        return self.plant.done

    @done.setter
    def done(self, value: bool) -> None:  # a signal ends the run (the executor's handler)
        self.plant.done = value

    def stamp(self) -> tuple[int, int]:
        """The current state's stamp: sim time of the plant's step."""
        return step_stamp(self.stepper.steps, self.spec.rate)

    def status(self) -> dict[str, str]:
        return {"step": str(self.stepper.steps), "safe_mode": self.plant.safe_mode,
                "rejected_commands": str(self.plant.rejected), "diverged": self.plant.failure or "no"}

    def publish_state(self) -> None:
        step = self.stepper.steps
        sec, nanosec = step_stamp(step, self.spec.rate)
        if self.mode == "lockstep" and step % self.clock_every == 0:
            self.pub_clock.publish(encode_clock(sec, nanosec))
        q, qd, applied = self.stepper.q, self.stepper.qd, self.plant.applied
        outputs = None  # end effector and passive joints (robots.compiled.outputs), when needed
        if self.n_passive:
            outputs = self.stepper.outputs().tolist()
            passive = self.n_passive
            position, velocity = q.tolist() + outputs[2:2 + passive], qd.tolist() + outputs[4:4 + passive]
            effort = applied.tolist() + [0.0] * passive
        else:
            position, velocity, effort = q.tolist(), qd.tolist(), applied.tolist()
        encoded = encode_joint_state(sec, nanosec, self.names, position, velocity, effort)
        self.pub_state.publish(encoded)
        if step % self.throttle_every == 0:
            self.pub_throttled.publish(encoded)
        if step % self.ee_every and step != self.plant.last_step:
            return  # the end-effector point goes out at the statistics rate
        if outputs is None:
            outputs = self.stepper.outputs().tolist()
        self.pub_ee.publish(encode_point_stamped(sec, nanosec, outputs[0], outputs[1]))

    def listeners_ready(self) -> bool:
        return (self.pub_state.participants() >= self.expected
                and self.pub_ee.participants() >= 1 and self.node.count_publishers(TOPIC_EFFORT) >= 1)

    def try_start(self) -> None:
        """Lockstep: publish state 0 once every participant is listening."""
        if not self.plant.started and self.listeners_ready():
            self.timer.cancel()
            self.plant.start(time.monotonic())

    def on_effort(self, data: bytes) -> None:
        try:
            step, values = decode_float64_multi_array(data)
        except CdrError as exc:
            self.plant.reject(str(exc))
            return
        self.plant.effort(step, values, time.monotonic())

    def tick(self, lateness: float) -> None:
        """Real time: one period (:meth:`SupervisedPlant.tick`)."""
        self.plant.tick(lateness / self.period, self.listeners_ready, time.monotonic())


def main(args: Sequence[str] | None = None) -> int:
    return run_node("plant", PlantNode, args)


if __name__ == "__main__":
    sys.exit(main())
