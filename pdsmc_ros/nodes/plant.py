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

``/robot_description`` (``std_msgs/String``, transient local, as
robot_state_publisher publishes it): the URDF of the arm, generated from
``config/robots.yaml`` (:mod:`pdsmc_ros.urdf`: the arms in the x-z plane, z up).
"""

from __future__ import annotations

import sys
import time
from collections.abc import Sequence

import numpy as np
from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import PointStamped
from rclpy.node import Node
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray, String

from ..bag.cdr import (
    decode_float64_multi_array,
    encode_clock,
    encode_joint_state,
    encode_point_stamped,
)
from ..bag.stamps import step_stamp
from ..errors import CdrError
from ..presets import robot_params
from ..safety import Watchdog, check_effort, safe_torque
from ..simulator import PlantStepper, control_steps
from ..urdf import robot_urdf
from .executor import run_node
from .io import GuardedPublisher, Inputs
from .lifecycle import EXIT_OK
from .params import (
    decimation,
    declare_busy_wait,
    declare_int_parameter,
    declare_run_parameters,
    declare_safety_parameters,
    refuse_run_changes,
    run_spec_from_parameters,
    safety_from_parameters,
)
from .topics import (
    LATCHED_QOS,
    STEADY_CLOCK,
    STREAM_QOS,
    TOPIC_DIAGNOSTICS,
    TOPIC_EE_ACTUAL,
    TOPIC_EFFORT,
    TOPIC_JOINT_STATES,
    TOPIC_ROBOT_DESCRIPTION,
)

MAX_CATCH_UP = 100  # real time: periods a late tick integrates at most besides its own


class PlantNode:
    """Thin wrapper: parameters, QoS and topics around :class:`PlantStepper`."""

    publishes_states = True  # composed in real time: its end is the end of the states

    def __init__(self) -> None:
        self.node = Node("plant")
        node = self.node
        declare_run_parameters(node)
        self.busy_wait = declare_busy_wait(node)  # used in real time
        self.expected = declare_int_parameter(
            node,
            "expected_subscribers",
            3,
            "subscribers of /joint_states to wait for (trajectory, controller, recorder)",
            lo=0,
            hi=100,
        )
        declare_safety_parameters(node)
        self.spec = run_spec_from_parameters(node)
        self.safety = safety_from_parameters(node)
        node.add_on_set_parameters_callback(refuse_run_changes)
        self.watch = Watchdog(rate=self.spec.rate,
                              timeout_s=float(node.get_parameter("watchdog_timeout").value),
                              periods=int(node.get_parameter("watchdog_periods").value),
                              time_scale=float(node.get_parameter("safe_time_scale").value))
        self.mode = node.get_parameter("mode").value
        reference = self.spec.reference()
        self.robot = self.spec.robot_model()
        q0 = reference.sample([0.0]).q[0]
        self.plant = PlantStepper(self.robot, 1.0 / self.spec.rate, q0, np.zeros(self.robot.n))
        self.plant.warm_up()  # not on the first step (numba loads the kernel)
        self.last_step = control_steps(reference.duration, self.spec.rate)
        self.applied = np.zeros(self.robot.n)
        self.latest_effort = np.zeros(self.robot.n)
        self.names = list(self.robot.joint_names) + list(self.robot.passive_joint_names)
        self.n_passive = len(self.robot.passive_joint_names)
        self.done = False
        self.exit_code = EXIT_OK
        self.rejected = 0
        self.started = False
        self.q_hold = self.plant.q.copy()
        self.rejected_reasons: dict[str, int] = {}
        self.clock_every = decimation(self.spec.rate, node.get_parameter("clock_rate").value)
        self.ee_every = self.spec.sample_every

        self.pub_state = GuardedPublisher(node.create_publisher(JointState, TOPIC_JOINT_STATES, STREAM_QOS), node)
        self.pub_ee = GuardedPublisher(node.create_publisher(PointStamped, TOPIC_EE_ACTUAL, STREAM_QOS), node)
        self.pub_clock = GuardedPublisher(node.create_publisher(Clock, "/clock", STREAM_QOS), node)
        self.pub_diag = GuardedPublisher(node.create_publisher(DiagnosticArray, TOPIC_DIAGNOSTICS, STREAM_QOS), node)
        self.pub_urdf = node.create_publisher(String, TOPIC_ROBOT_DESCRIPTION, LATCHED_QOS)
        self.pub_urdf.publish(String(data=robot_urdf(
            self.spec.robot, robot_params(self.spec.robot), self.spec.payload)))
        self.inputs = Inputs(node, self.mode)
        self.inputs.subscribe(Float64MultiArray, TOPIC_EFFORT, self.on_effort)

        if self.mode == "lockstep":
            self.timer = node.create_timer(0.01, self.try_start, clock=STEADY_CLOCK)
            self.watchdog = node.create_timer(0.01, self.check_watchdog, clock=STEADY_CLOCK)
        else:
            self.period = 1.0 / self.spec.rate  # run_node paces tick() at this period
        node.get_logger().info(
            f"{self.spec.robot} plant, {self.mode}, {self.spec.rate:g} Hz, "
            f"{self.last_step} steps, payload {self.spec.payload:g} kg"
        )

    # -- publishing --------------------------------------------------------- #
    def publish_state(self) -> None:
        step = self.plant.steps
        sec, nanosec = step_stamp(step, self.spec.rate)
        if self.mode == "lockstep" and step % self.clock_every == 0:
            self.pub_clock.publish(encode_clock(sec, nanosec))
        q, qd = self.plant.q, self.plant.qd
        outputs = None  # end effector and passive joints (kernels.robot_outputs), when needed
        if self.n_passive:
            outputs = self.plant.outputs().tolist()
            passive = self.n_passive
            position, velocity = q.tolist() + outputs[2:2 + passive], qd.tolist() + outputs[4:4 + passive]
            effort = self.applied.tolist() + [0.0] * passive
        else:
            position, velocity, effort = q.tolist(), qd.tolist(), self.applied.tolist()
        self.pub_state.publish(encode_joint_state(sec, nanosec, self.names, position, velocity, effort))
        if step % self.ee_every and step != self.last_step:
            return  # the end-effector point goes out at the statistics rate
        if outputs is None:
            outputs = self.plant.outputs().tolist()
        self.pub_ee.publish(encode_point_stamped(sec, nanosec, outputs[0], outputs[1]))

    def listeners_ready(self) -> bool:
        return (
            self.pub_state.get_subscription_count() >= self.expected
            and self.pub_ee.get_subscription_count() >= 1
            and self.node.count_publishers(TOPIC_EFFORT) >= 1
        )

    def try_start(self) -> None:
        """Lockstep: publish state 0 once every participant is listening."""
        if self.started:
            return
        if self.listeners_ready():
            self.started = True
            self.timer.cancel()
            self.publish_state()

    # -- effort ------------------------------------------------------------- #
    def reject(self, reason: str) -> None:
        """Count a refused effort command; log the first few and then every 1000th."""
        self.rejected += 1
        key = reason.split(" (")[0]
        self.rejected_reasons[key] = self.rejected_reasons.get(key, 0) + 1
        if self.rejected <= 5 or self.rejected % 1000 == 0:
            self.node.get_logger().warn(
                f"rejected effort command: {reason}; {self.rejected} rejected so far {self.rejected_reasons}"
            )
            self.diagnose(DiagnosticStatus.WARN, f"rejected effort command: {reason}")

    def diagnose(self, level: bytes, message: str) -> None:
        """Publish the plant's status on /diagnostics (recorded in the bag)."""
        status = DiagnosticStatus(level=level, name="pdsmc_ros/plant", message=message, hardware_id=self.spec.robot)
        status.values = [
            KeyValue(key="step", value=str(self.plant.steps)),
            KeyValue(key="safe_mode", value=self.safety.mode if self.watch.safe else "off"),
            KeyValue(key="rejected_commands", value=str(self.rejected)),
        ]
        msg = DiagnosticArray(status=[status])
        sec, nanosec = step_stamp(self.plant.steps, self.spec.rate)
        msg.header.stamp = Time(sec=sec, nanosec=nanosec)
        self.pub_diag.publish(msg)

    def on_effort(self, data: bytes) -> None:
        try:
            step, values = decode_float64_multi_array(data)
        except CdrError as exc:
            self.reject(str(exc))
            return
        lockstep = self.mode == "lockstep"
        tau, reason = check_effort(values, self.robot.n)
        if tau is None:
            self.reject(reason)
            return
        if not lockstep:
            self.latest_effort = tau
            if self.watch.effort(time.monotonic()):
                self.report_resumed()
            return
        if step != self.plant.steps:
            if self.watch.offer_resume():
                # a controller is back: stop stepping alone and offer it the current state
                self.publish_state()
            self.reject(f"out of order (step {step}, expected {self.plant.steps})")
            return
        if self.watch.effort(time.monotonic()):
            self.report_resumed()
        if step >= self.last_step:
            self.done = True  # the controller's effort for t = T closes the run
            return
        self.plant.step(tau)
        self.applied = tau
        self.publish_state()

    # -- watchdog and safe mode ---------------------------------------------- #
    def check_watchdog(self) -> None:
        """Lockstep: no effort within ``watchdog_timeout`` s of wall time -> safe mode."""
        if not self.started or self.done:
            return
        now = time.monotonic()
        if self.watch.lost_in_lockstep(now):
            self.enter_safe_mode(f"no effort for step {self.plant.steps} within {self.watch.timeout_s:g} s")
            return
        # safe mode: the arm advances with the safe torque, supervised, while no controller answers
        for _ in range(self.watch.safe_steps_owed(now)):
            if self.plant.steps >= self.last_step:
                self.done = True
                return
            self.safe_step()

    def safe_step(self) -> None:
        tau = safe_torque(self.safety, self.plant.q, self.plant.qd, self.q_hold)
        self.plant.step(tau)
        self.applied = tau
        self.publish_state()

    def enter_safe_mode(self, why: str) -> None:
        self.watch.enter(time.monotonic())
        self.q_hold = self.plant.q.copy()
        text = f"controller lost: {why}; safe mode '{self.safety.mode}'"
        self.node.get_logger().error(text)
        self.diagnose(DiagnosticStatus.ERROR, text)
        if self.safety.on_loss == "end":
            self.node.get_logger().error("ending the run (on_controller_loss:=end)")
            self.done = True

    def report_resumed(self) -> None:
        text = f"controller back at step {self.plant.steps}: safe mode off"
        self.node.get_logger().info(text)
        self.diagnose(DiagnosticStatus.OK, text)

    def tick(self, lateness: float) -> None:
        """Real time: publish the state, then integrate one period with the latest effort.

        Until the first effort arrives the arm is held at its initial state (the
        controller may still be starting), so the run begins under control. When
        the loop was more than two periods late it skips the ticks it missed
        (:func:`~pdsmc_ros.nodes.executor._serve_loop` resynchronises); the arm's
        time does not stop meanwhile, so the plant integrates those periods too
        (at most ``MAX_CATCH_UP``): its time stays the wall clock's, which the
        nodes downstream keep on their own clocks.
        """
        missed = min(int(lateness / self.period), MAX_CATCH_UP) if lateness > 2.0 * self.period else 0
        for _ in range(1 + missed):
            self.step_once()
            if self.done or not self.started:
                return

    def step_once(self) -> None:
        self.publish_state()
        if not self.started:
            # start once everyone listens (the recorder too) and the controller answers
            self.started = self.watch.armed and self.listeners_ready()
            return
        if self.plant.steps >= self.last_step:
            self.done = True
            return
        if self.watch.lost_in_period():
            self.enter_safe_mode(f"no effort for {self.watch.periods} periods")
            if self.done:
                return
        if self.watch.safe:
            self.applied = safe_torque(self.safety, self.plant.q, self.plant.qd, self.q_hold)
        else:
            self.applied = self.latest_effort
        self.plant.step(self.applied)


def main(args: Sequence[str] | None = None) -> int:
    return run_node("plant", PlantNode, args)


if __name__ == "__main__":
    sys.exit(main())
