"""Trajectory generator node: joint references and the desired end-effector point.

Publishes ``/reference`` every control step (``trajectory_msgs/JointTrajectory``
with one point: positions, velocities, accelerations; stamped with the control
instant) and ``/end_effector/desired`` at the statistics rate. The references of every control instant are
computed once at start with the same vectorised call as the in-process
simulator, so both see bit-identical references.

Lockstep: references ``0 .. W`` are published once the subscribers listen, then
up to ``k + W`` as soon as joint state ``k`` arrives (``W = lookahead_steps``,
500 by default), so the controller never waits for a reference and the
trajectory is off the loop's critical path: it takes the plant's states in
batches (like the recorder) instead of waking once per step. ``W`` stays well
below the publishers' history depth, so nothing sent ahead can be lost.

Real time: at the control rate, the reference one step ahead of the node's
own clock, which starts when the plant's time does -- at the first state whose
stamp differs from the first state's (this package's plant holds its initial
state, stamp unchanged, until the controller answers; a driver's wall-clock
stamps change with every message). Stamps are compared, never read as a step,
so the thesis's contours can drive any arm. After the contour's end the last
reference is held; the node ends when the plant leaves the graph.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Sequence

import numpy as np
from geometry_msgs.msg import PointStamped
from rclpy.node import Node
from sensor_msgs.msg import JointState
from trajectory_msgs.msg import JointTrajectory

from ..bag.cdr import decode_stamp, encode_point_stamped
from ..bag.stamps import stamp_step, step_stamp
from ..errors import CdrError
from ..loop.inputs import Inputs
from ..loop.lifecycle import EXIT_OK, WATCH_GRACE_S, end_when_plant_leaves
from ..loop.process import run_node
from ..parameters import TRAJECTORY
from ..parameters.ros import declare
from ..parameters.tables import TRAJECTORY_PRIORITY
from ..ros.node_run import declare_node_run
from ..ros.publishers import GuardedPublisher
from ..ros.topics import STEADY_CLOCK, STREAM_QOS, TOPIC_EE_DESIRED, TOPIC_JOINT_STATES, TOPIC_REFERENCE
from ..runs.builder import control_steps
from .reference_windows import ReferenceWindows

TRAJECTORY_BATCH_S = 0.002  # lockstep: take the plant's states every 2 ms, in batches


class TrajectoryNode:
    """Thin wrapper around :class:`~pdsmc_ros.contours.JointReference`."""

    realtime_priority = TRAJECTORY_PRIORITY  # thread_priority's default in real time: below the plant's

    def __init__(self) -> None:
        self.node = Node("trajectory")
        node = self.node
        run = declare_node_run(node)
        self.spec, self.mode, self.busy_wait = run.spec, run.mode, run.busy_wait
        own = declare(node, TRAJECTORY)  # read-only, as the run's (declare_node_run guards them)
        self.expected, self.lookahead = own["expected_subscribers"], own["lookahead_steps"]
        reference = self.spec.reference()
        self.robot = self.spec.robot_model()
        self.last_step = control_steps(reference.duration, self.spec.rate)
        t = np.arange(self.last_step + 1) / self.spec.rate
        self.refs = reference.sample(t)
        self.task = reference.contour.task(t).p
        self.names = list(self.robot.joint_names)
        self.ee_every = self.spec.sample_every
        self.next_step = 0
        self.state_step = -1
        self.states_received = 0
        self.first_stamp: tuple[int, int] | None = None  # real time: the plant's first state
        self.clock_start_logged = False  # real time: the clock's start is logged in spare time
        self.clock_start: float | None = None  # real time: perf_counter() at the plant's t = 0
        self.references = ReferenceWindows(self.refs.q, self.refs.qd, self.refs.qdd, self.names, self.spec.rate)
        self.started = False
        self.done = False
        self.exit_code = EXIT_OK

        self.pub_ref = GuardedPublisher(node.create_publisher(JointTrajectory, TOPIC_REFERENCE, STREAM_QOS), node)
        self.pub_ee = GuardedPublisher(node.create_publisher(PointStamped, TOPIC_EE_DESIRED, STREAM_QOS), node)
        # lockstep: off the critical path (references go out W steps ahead), so batched
        self.inputs = Inputs(node, self.mode, batch_s=TRAJECTORY_BATCH_S if self.mode == "lockstep" else 0.0)
        # lockstep: an observer's batches (see Inputs); real time: each state
        self.inputs.subscribe(JointState, TOPIC_JOINT_STATES,
                              self.on_states if self.mode == "lockstep" else self.on_state)
        if self.mode == "lockstep":
            self.timer = node.create_timer(0.01, self.try_start, clock=STEADY_CLOCK)
        else:
            self.period = 1.0 / self.spec.rate  # run_node paces tick() at this period
            self.plant_watch = end_when_plant_leaves(self, lambda: self.states_received)
        node.get_logger().info(
            f"{self.spec.contour} for {self.spec.robot}: {reference.duration:g} s, "
            f"{self.last_step + 1} references"
        )

    def publish(self, step: int) -> None:
        self.pub_ref.publish(self.references[step])
        if step % self.ee_every and step != self.last_step:
            return  # the desired end-effector point goes out at the statistics rate
        sec, nanosec = step_stamp(step, self.spec.rate)
        self.pub_ee.publish(encode_point_stamped(sec, nanosec, float(self.task[step, 0]), float(self.task[step, 1])))

    def try_start(self) -> None:
        if (
            self.pub_ref.participants() >= self.expected
            and self.pub_ee.participants() >= 1
        ):
            self.timer.cancel()
            self.started = True
            self.advance()

    def advance(self) -> None:
        """Publish every reference up to ``lookahead_steps`` ahead of the latest state."""
        while self.next_step <= min(self.state_step + self.lookahead, self.last_step):
            self.publish(self.next_step)
            self.next_step += 1

    def on_states(self, batch: list[bytes]) -> None:
        for data in batch:
            self.on_state(data)

    def on_state(self, data: bytes) -> None:
        try:
            stamp = decode_stamp(data)
        except CdrError:
            self.node.get_logger().error("malformed /joint_states message ignored", throttle_duration_sec=1.0)
            return
        self.states_received += 1
        if self.mode != "lockstep":
            if self.first_stamp is None:
                self.first_stamp = stamp
            elif self.clock_start is None and stamp != self.first_stamp:
                # the plant's time has started: this state is one period after its start
                self.clock_start = time.perf_counter() - self.period
            return
        step = stamp_step(*stamp, self.spec.rate)
        repeated = step == self.state_step
        self.state_step = max(self.state_step, step)
        if self.started:
            if repeated and step < self.next_step:
                # the plant offers this state again (a controller came back after safe
                # mode): a new controller has seen none of the references sent ahead
                for k in range(step, self.next_step):
                    self.publish(k)
            self.advance()
        if step >= self.last_step:
            self.done = True

    def tick(self, lateness: float) -> None:  # noqa: ARG002
        """Real time: at the control rate, the reference one step ahead of the own clock
        (the first reference until the plant's time starts; the last one after the end)."""
        step = 0
        if self.clock_start is not None:
            step = min(int((time.perf_counter() - self.clock_start) * self.spec.rate) + 1, self.last_step)
        self.publish(step)
        self.plant_watch.poll(grace=WATCH_GRACE_S)  # only if the loop had no spare time for it

    def idle(self, until: float) -> None:
        """Real time, in the loop's spare time after a tick: the next window of references
        serialized ahead, a piece at a time, and a look at whether the plant is there."""
        self.plant_watch.poll()
        if self.clock_start is not None and not self.clock_start_logged:
            # here, not where the clock starts: a log line (console and /rosout) costs a large
            # share of a control period, which the state handler must not spend
            self.clock_start_logged = True
            self.node.get_logger().info("the plant's time has started: contour clock running")
        self.references.encode_ahead(until)


def main(args: Sequence[str] | None = None) -> int:
    return run_node("trajectory", TrajectoryNode, args)


if __name__ == "__main__":
    sys.exit(main())
