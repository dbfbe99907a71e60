"""Controller node: PD, SMC or PD-SMC (any registered law), selected with ``-p type:=pdsmc``.

A managed (lifecycle) node, configured and activated at start unless ``autostart:=false``.
In: ``/joint_states`` and three reference sources, ``/reference`` (one point per step),
``~/joint_trajectory`` (JointTrajectory, as joint_trajectory_controller) and the action
``~/follow_joint_trajectory`` (:mod:`.action`, served by a node of its own: real time, in a
process of its own, :mod:`.sidecar.goal_process`; lockstep, in a thread of its own); whichever spoke
last drives. Real time: on activation, and after
a goal is canceled or aborted, the controller holds the position it measures (through the
chosen law); a trajectory's time is the node clock (``header.stamp``, or the reception
time when zero). Joints by name (``joints``, any order, mapped onto the robot's). Out:
torques on ``/effort_controller/commands`` (``data[i]`` for ``joints[i]``, within the arm's soft
limits: :mod:`.parameters`), ``~/controller_state``, ``/pdsmc/run_description`` (latched) and
``/diagnostics``. Parameters are validated on set (gains: their stability check at the running
rate); real time, the parameter services are the goal process's, which declares the node's
parameters as they are and hands accepted gains to the loop. Real time: a joint running away
(beyond its velocity limit by ``runaway.velocity_factor``, beyond a position limit) aborts the
active goal and latches a stop until the next activation; the node then exits 1. Lockstep pairs the
state and the reference of each step (no hold: the plant waits for its command). Stopping (signal,
lifecycle, stale inputs) publishes one zero command.
A law with internal state (an integrator: ``sta``, ``ismc``) starts from zero at each activation
and integrates it once per command with the nominal period ``1 / rate`` (not the measured one).
"""

from __future__ import annotations

import dataclasses
import sys
import threading
import time
from collections.abc import Callable, Sequence

from control_msgs.action import FollowJointTrajectory
from control_msgs.msg import JointTrajectoryControllerState
from rclpy.duration import Duration
from rclpy.lifecycle import LifecycleNode, LifecycleState, TransitionCallbackReturn
from rclpy.node import Node
from rclpy.parameter_service import ParameterService
from rclpy.serialization import deserialize_message
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray, String
from trajectory_msgs.msg import JointTrajectory

from ..bag.cdr import encode_float64_multi_array
from ..control import Gains
from ..control.stability import check_rate
from ..loop.inputs import Inputs, Times
from ..loop.lifecycle import EXIT_FAILURE, EXIT_OK, WATCH_GRACE_S, CommandingEntity, end_when_plant_leaves
from ..loop.log import LoopLog
from ..loop.process import run_node
from ..loop.realtime_params import declare_realtime_parameters
from ..loop.statistics import LoopStatistics
from ..robots.base import FloatArray
from ..ros import topics
from ..ros.diagnostics import Diagnostics, InputReport
from ..ros.node_run import description_json
from ..ros.publishers import GuardedPublisher, RowBatches
from .action import FollowJointTrajectoryServer, controller_state_topic, goal_event_topic, topic_trajectory
from .commanding import Paired, TorqueGuard
from .core import ControllerCore, GoalStart, Tolerance
from .goals import GoalExecution
from .joint_trajectory import JointTrajectoryReference, RawPoint
from .joints import JointSelector
from .limits import JointLimits
from .parameters import GainUpdates, declare_controller_parameters, declare_controller_run, declare_limit_parameters
from .sidecar.gain_check import CheckProcess, checked
from .sidecar.goal_process import GoalProcess, parameter_table, setup_of, uses_goal_process
from .sidecar.lost_results import LostResults

GOAL_BATCH_S = 0.002  # ~/joint_trajectory is looked at every 2 ms
GOAL_PROCESS_START_S = 60.0  # real time: how long the node waits for its goal process to serve the action
STOP_ACK_S = 0.5  # how long a stopping controller waits for its zero command to be acknowledged
SERVE_POLL_S = 0.005  # real time: how often the action's server looks for the first complete state
SERVE_WAIT_NOTE_S = 5.0  # ... and after how long it says it is waiting


class EffortOutput:
    """The effort commands of a controller (``Float64MultiArray``, ``data[i]`` for joint ``i``,
    ``layout.data_offset`` the control step): never a non-finite torque, clamped to the limits,
    and one zero command when it stops commanding (a forward command controller holds the last
    command forever). Its lines go to ``log`` (the loop's thread publishes: :class:`~pdsmc_ros.loop.log.LoopLog`)."""

    def __init__(self, node: Node, topic: str, n: int, guard: TorqueGuard, *, log: LoopLog | None = None,
                 writer_thread: bool = False) -> None:
        self.node = node
        self.log = log if log is not None else LoopLog(node)
        # real time: the middleware's writes in a thread of their own (never a tick waiting in Fast DDS)
        self.pub = GuardedPublisher(node.create_publisher(Float64MultiArray, topic, topics.STREAM_QOS), node,
                                    writer_thread=writer_thread)
        self.n = n
        self.guard = guard
        self.commanding = False  # a torque may be the last command on the wire
        # real time: lifecycle transitions run in the executor's thread; no torque may follow the zero command
        self.lock = threading.Lock()

    def publish(self, tau: FloatArray, step: int) -> None:
        values, note = self.guard.check(tau)
        if note and values is None:
            self.log.error(note)
        elif note:
            self.log.warn(note)
        if values is not None:
            self.pub.publish(encode_float64_multi_array(values, step))
            self.commanding = True

    def stop(self, why: str, step: int) -> bool:
        """Publish one zero command for ``step`` if a torque may be the last on the wire (whether it did)."""
        with self.lock:
            if not self.commanding:
                return False
            self.pub.publish(encode_float64_multi_array([0.0] * self.n, step))
            self.commanding = False
        self.log.warn(f"{why}: zero effort published, output stopped")
        return True

    def close(self, timeout: float) -> None:
        """Every command handed over written (up to ``timeout`` s), the writer's summary logged, its thread ended."""
        writer = self.pub.writer
        if writer is not None:
            if not writer.flush(timeout):
                self.node.get_logger().error(f"{self.pub.publisher.topic_name}: the last commands handed over were not "
                                             f"written within {timeout:g} s")
            writer.close()
            self.node.get_logger().info(writer.summary())


class ControllerNode(CommandingEntity):
    """Wiring around :class:`~pdsmc_ros.controller.core.ControllerCore` (the decisions:
    inputs, holds, goals, the law's torque): parameters, topics, logs and the lifecycle."""

    def __init__(self) -> None:
        # the parameter services: real time, the goal process's (sidecar.parameter_stand_in), else this node's
        self.node = node = LifecycleNode("controller", start_parameter_services=False)
        run = declare_controller_run(node)  # its parameters, the gains given resolved into run.spec
        self.mode, self.busy_wait, self.lockstep = run.mode, run.busy_wait, run.mode == "lockstep"
        robot = run.spec.robot_model()
        self.params = params = declare_controller_parameters(node, robot)
        self.joint_map = params.joint_map
        # the description says whether the clamp runs, so simulate(spec) of the bag repeats the run
        spec = dataclasses.replace(run.spec, enforce_limits=params.enforce_limits)  # gains in robot order
        soft_table, runaway = declare_limit_parameters(node, robot, params, 1.0 / spec.rate, self.lockstep,
                                                       spec.reference().sample([0.0]).q[0])
        self.guard = TorqueGuard(soft_table)
        self.limits_report = Diagnostics(node, "controller: limits", spec.robot)
        self.loop_log = LoopLog(node)  # lines of the loop's thread, written by the executor's
        self.core = core = ControllerCore(
            spec, JointSelector(robot.joint_names), self.joint_map,  # the law's vectors stay in robot order
            JointLimits.of(robot, robot.joint_names) if params.enforce_limits else None, self.guard,
            params.stale_periods / spec.rate, self.lockstep,
            lambda why: self.loop_log.info(f"holding the measured position ({why})"),
            runaway=runaway, on_runaway=self.on_runaway, goal_settings=params.goal_settings)
        in_process = lambda new: check_rate(new, core.reference, **run.stability)  # noqa: E731 - used twice below
        checked(in_process, spec)  # refuse gains unstable here
        # gains: the on-set callback checks a change is stable at the running rate, the post-set one applies
        # it (real time: the goal process serves the parameters and checks; serve_parameters_here otherwise)
        self.stability = run.stability
        self.gain_check: CheckProcess | None = None
        self.gain_updates = GainUpdates(node, spec, in_process, self.apply_gains, joint_map=self.joint_map)
        self.active = self.done = False  # commanding; the run is over
        self.exit_code = EXIT_OK

        description = String(data=description_json(spec, self.mode))
        node.create_publisher(String, topics.TOPIC_DESCRIPTION, topics.LATCHED_QOS).publish(description)
        if not self.lockstep:
            self.period = 1.0 / spec.rate  # run_node paces tick() at this period
            # the loop's one statistics object: the serve loop records each tick in it (and publishes
            # it on /diagnostics), the timing rows read it
            self.loop_statistics = LoopStatistics(self.period)
            self.timing_rows = RowBatches(node, topics.TOPIC_TIMING, ("tick", "field"), LoopStatistics.ROW_FIELDS,
                                          batch=50)
            self.plant_watch = end_when_plant_leaves(self, lambda: core.states_received)
        node.add_managed_entity(self)
        # the action server: real time, in a thread of this process, or with goal_process on, in a process of its
        # own (goal_process); lockstep, a node of its own spun by a thread of its own, never by the loop's
        # executor. With a goal process, this node publishes the server's state and goal events (serialized
        # there): a recorder already knows this participant
        self.published_here = {} if self.lockstep else self.raw_publishers()
        declare_realtime_parameters(node, self.mode)  # before the goal process takes every parameter (run_node reads)
        in_child = not self.lockstep and uses_goal_process(params.goal_process)
        # the result of a goal lost with the goal process, for its client (the child held the request)
        self.lost_results = LostResults(node, node.get_fully_qualified_name()) if in_child else None
        self.goal_process = None if not in_child else GoalProcess.for_controller(
            setup_of(spec=spec, name=node.get_name(), namespace=node.get_namespace(),
                     base=node.get_fully_qualified_name(), joints=params.joints, joint_map=self.joint_map,
                     robot_joints=robot.joint_names, limits=core.limits, goal_settings=core.goal_settings,
                     action_introspection=params.action_introspection,
                     topics={topics.TOPIC_JOINT_TRAJECTORY: node.resolve_topic_name(topics.TOPIC_JOINT_TRAJECTORY)},
                     use_sim_time=bool(node.get_parameter("use_sim_time").value),
                     parameters=parameter_table(node), stability=run.stability),
            core, lambda: self.guard.clamped, on_lost=lambda why: self.loop_log.error(why),
            on_restored=lambda what: node.get_logger().info(what), publishers=self.published_here,
            on_gains=self.gain_updates.take,
            parameters_now=lambda: parameter_table(node, self.gain_updates.given), results=self.lost_results)
        self.action: FollowJointTrajectoryServer | None = None
        # lockstep, the loop takes ~/joint_trajectory: its status, shared with the action server
        self.trajectory_report = Diagnostics(node, "controller: trajectories", spec.robot) if self.lockstep else None
        if self.goal_process is not None:
            self.goal_process.start()  # from this thread, at normal scheduling; it starts while the node configures
        if params.autostart:
            # configured (the law's kernel loaded, the path from a message to a command warmed up) before
            # the robot's topics exist: a plant that starts once it sees them is answered at once, and a
            # lockstep plant never sends its first state again to a controller that is only slow to start
            node.trigger_configure()
        self.effort = EffortOutput(node, topics.TOPIC_EFFORT, robot.n, self.guard, log=self.loop_log,
                                   writer_thread=not self.lockstep)
        self.report_input = InputReport(Diagnostics(node, "controller: inputs", spec.robot,
                                                    values=lambda: {"joints": ",".join(self.params.joints)}))
        self.inputs = Inputs(node, self.mode)
        self.inputs.subscribe(JointState, topics.TOPIC_JOINT_STATES, self.on_state)
        self.inputs.subscribe(JointTrajectory, topics.TOPIC_REFERENCE, self.on_reference)
        # off the loop's path: a goal is rare, and an input taken at every pass of the loop costs a take per pass;
        # real time: taken and validated by the action server's thread, never the loop's
        self.observed_inputs = Inputs(node, self.mode, batch_s=GOAL_BATCH_S, suffix="_goals")
        if self.goal_process is not None and not self.goal_process.wait_ready(GOAL_PROCESS_START_S):
            node.get_logger().error(f"the goal process did not start within {GOAL_PROCESS_START_S:g} s: "
                                    "the action is served in the controller's process")
            self.goal_process.close()
            self.goal_process = None
        if self.goal_process is None and self.lost_results is not None:
            self.lost_results.destroy()  # the action's server in this process answers every result
            self.lost_results = None
        if self.goal_process is None:
            self.serve_parameters_here()
        if params.autostart:
            node.trigger_activate()
        # the action and ~/joint_trajectory from here on, after the activation at start: a client that sees
        # the server or the subscription finds the controller active (as joint_trajectory_controller's, they
        # exist while it is only configured too: autostart:=false)
        self.serve_goals()
        waiting = "" if params.autostart else "; unconfigured until configure and activate"
        node.get_logger().info(f"{spec.controller} controller for {spec.robot}/{spec.contour}, {self.mode}, "
                               f"{spec.rate:g} Hz, joints {list(params.joints)}{waiting}")

    @property
    def active(self) -> bool:
        """Commanding (the lifecycle's active state): told to the goal process as it changes."""
        return self._active

    @active.setter
    def active(self, value: bool) -> None:
        self._active = value
        goal_process = getattr(self, "goal_process", None)
        if goal_process is not None:
            goal_process.set_active(value)

    def on_runaway(self, why: str) -> None:
        """The runaway guard tripped (the loop's thread): reported, and the run fails."""
        stop = self.core.runaway.stop if self.core.runaway is not None else ""
        if self.goal_process is not None:
            self.goal_process.tell_runaway(why)
        self.limits_report.report("error", f"{why}: active goal aborted, {stop} stop until the controller is "
                                           "deactivated and activated again")
        self.exit_code = EXIT_FAILURE

    def configure(self) -> None:
        self.core.configure()  # the law's kernel and the path from a message to a command, warmed up

    def on_activate(self, state: LifecycleState) -> TransitionCallbackReturn:
        self.core.activate()
        if self.goal_process is not None:
            self.goal_process.tell_runaway("")  # reset by the activation
        return super().on_activate(state)

    def on_deactivate(self, state: LifecycleState) -> TransitionCallbackReturn:
        self.core.goals.end("Current goal cancelled during deactivate transition.")  # as joint_trajectory_controller
        return super().on_deactivate(state)

    def cleanup(self) -> None:
        self.core.law = None

    def apply_gains(self, gains: Gains) -> None:
        """Gains accepted (:class:`~.parameters.GainUpdates`): the executor's thread, or real time the
        loop's spare time (the goal process serves the parameters)."""
        self.core.apply_gains(self.gain_updates.spec)
        self.loop_log.info(f"gains changed: {gains.as_dict()}")

    def serve_parameters_here(self) -> None:
        """The parameter services in this process (lockstep, or no goal process); real time, the gains'
        check in a process of its own (50-100 ms of numpy, never beside the loop)."""
        if not self.lockstep:
            self.gain_check = CheckProcess.for_run(self.gain_updates.spec, self.stability)
            if self.gain_check is not None:
                self.gain_check.start()  # from this thread, at normal scheduling, while the node starts
                self.gain_updates.check = self.gain_check
                self.node.get_logger().info(f"the gains' check runs in a process of its own "
                                            f"(pid {self.gain_check.pid})")
        ParameterService(self.node)

    def serve_goals(self) -> None:
        """The action server, ``~/query_state`` and ``~/joint_trajectory``: lockstep, at once (the loop
        takes ``~/joint_trajectory``); real time, once the controller has a complete measured state (a
        goal starts from it: a client that sees the server is not refused for want of one), in the goal
        process (``~/joint_trajectory`` taken here, validated there) or in a thread of this process."""
        goals, trajectory = self.observed_inputs, topics.TOPIC_JOINT_TRAJECTORY
        if self.goal_process is not None:
            # the loop's inputs are fixed before it runs: the subscription now; what arrives before the child
            # serves waits there for it
            goals.subscribe(JointTrajectory, trajectory, self.goal_process.forward, topics.TRAJECTORY_QOS,
                            with_receipt=True)  # taken here as bytes, validated by the goal process
            self.goal_process.serve()  # the loop tells it once it has a complete state
            return
        if self.lockstep:
            goals.subscribe(JointTrajectory, trajectory, self.on_goals, topics.TRAJECTORY_QOS, with_receipt=True)
            self.serve_action()
            return
        threading.Thread(target=self.serve_when_measured, name="serve_goals", daemon=True).start()

    def serve_when_measured(self) -> None:
        """Real time, a thread of normal scheduling: the action server in this process once the
        controller has a complete measured state (said once if that takes long)."""
        began, said = time.monotonic(), False
        while not self.done and self.node.context.ok():
            if self.core.measured() is not None:
                self.serve_action()
                return
            if not said and time.monotonic() - began > SERVE_WAIT_NOTE_S:
                said = True
                self.node.get_logger().info(f"the action waits for a complete joint state on "
                                            f"{topics.TOPIC_JOINT_STATES} (none in {SERVE_WAIT_NOTE_S:g} s)")
            time.sleep(SERVE_POLL_S)

    def serve_action(self) -> None:
        self.action = FollowJointTrajectoryServer(LocalView(self), event_sink=self.published_here.get("goal_event"),
                                                  state_sink=self.published_here.get("controller_state"),
                                                  report=self.trajectory_report)

    def raw_publishers(self) -> dict[str, Callable[[bytes], None]]:
        """The goal process's messages this process publishes (serialized there), by kind."""
        node, base = self.node, self.node.get_fully_qualified_name()
        publishers = {"controller_state": node.create_publisher(JointTrajectoryControllerState,
                                                                controller_state_topic(base), 10).publish}
        if self.params.action_introspection != "disabled":
            publishers["goal_event"] = node.create_publisher(FollowJointTrajectory.Impl.SendGoalService.Event,
                                                             goal_event_topic(base), 10).publish
        return publishers

    # -- inputs --------------------------------------------------------------- #
    def on_state(self, data: bytes) -> None:
        paired, problem = self.core.add_state(data, topics.TOPIC_JOINT_STATES)
        if problem is not None or self.report_input.problem is not None:
            self.report_input(problem)  # a problem, or complete inputs again
        self.compute(paired)

    def on_reference(self, data: bytes) -> None:
        paired, problem = self.core.add_reference(data, topics.TOPIC_REFERENCE)
        if problem:
            self.report_input(problem)
        self.compute(paired)

    def now(self) -> float:
        """The controller's time (s): the lockstep state's sim time, else the node's clock."""
        return self.core.sim_time() if self.lockstep else self.node.get_clock().now().nanoseconds * 1e-9

    def on_goals(self, batch: list[tuple[bytes, Times]]) -> None:
        """Lockstep: trajectory goals taken in a batch, each replacing the previous one, in order."""
        report = self.trajectory_report
        if report is None:  # pragma: no cover - subscribed in lockstep only, where the status exists
            return
        for data, times in batch:
            try:
                msg = deserialize_message(data, JointTrajectory)
            except Exception as exc:  # noqa: BLE001 - any malformed message: refused, never fatal
                report.report("error", f"{topics.TOPIC_JOINT_TRAJECTORY}: malformed message ({exc})")
                continue
            if topic_trajectory(LocalView(self), msg, times, report):
                self.compute(self.core.pairing.take())

    def compute(self, paired: Paired | None) -> None:
        """Lockstep: the torque of a state paired with its reference."""
        if paired is not None:
            step, q, qd, ref = paired
            tau = self.core.command(step / self.core.spec.rate, q, qd, ref) if self.active else None
            if self.core.limit_note:
                self.node.get_logger().warn(self.core.limit_note)
            if tau is not None:
                self.effort.publish(self.joint_map.to_user(tau), step)
            self.done = self.core.pairing.finished

    def stop_commanding(self, why: str) -> bool:
        return self.effort.stop(why, self.core.pairing.stop_step if self.lockstep else 0)

    def tick(self, lateness: float) -> None:
        """Real time: a torque from the latest inputs (a goal checked against its tolerances),
        its timing recorded; then (rarely) a look at whether the plant is there."""
        stats = self.loop_statistics
        now = stats.last_start if stats.last_start is not None else time.perf_counter()
        if self.active:
            tau, change = self.core.realtime_command(now, self.now)
            if change == "stale":
                self.loop_log.error(f"state or reference older than {self.params.stale_periods} periods")
                self.stop_commanding("inputs stale")
            elif change == "fresh":
                self.loop_log.info("fresh state and reference again: output resumed")
            if self.core.limit_note:
                self.loop_log.warn(self.core.limit_note)
            if tau is not None:
                with self.effort.lock:
                    if self.active:
                        self.effort.publish(self.joint_map.to_user(tau), 0)
                self.timing_rows.add(stats.row(now, lateness))
        self.plant_watch.poll(grace=WATCH_GRACE_S)  # only if the loop had no spare time for it

    def idle(self, until: float) -> None:
        """Real time, in the loop's spare time after a tick: the goal process's requests and news
        for it (else the action's feedback and the controller state), and a look at whether the
        plant is there."""
        if self.goal_process is not None:
            self.goal_process.poll(time.perf_counter())
        elif self.action is not None:
            self.action.publish(until)
        self.plant_watch.poll()

    def close(self) -> None:
        """Stopping (signal, end of run): a zero command unless the lockstep run is complete."""
        if self.action is not None:
            self.action.stop()
        if self.goal_process is not None:
            self.goal_process.close()
        if self.lost_results is not None:
            self.lost_results.destroy()
        if self.gain_check is not None:
            self.gain_check.close()
        if not self.lockstep:
            self.timing_rows.flush()
        if self.guard.clamped:
            saturated = self.joint_map.to_user(self.guard.joint_saturated).tolist()
            self.node.get_logger().warn(f"torque limited by the soft limits in {self.guard.clamped} periods (at "
                                        f"the effort limit, per joint: {dict(zip(self.params.joints, saturated))})")
        stopped = not self.core.pairing.finished and self.stop_commanding("stopping")  # complete: the plant has ended
        self.effort.close(STOP_ACK_S)
        if stopped:
            self.effort.pub.publisher.wait_for_all_acked(Duration(nanoseconds=int(STOP_ACK_S * 1e9)))


class LocalView:
    """The controller node as its action server sees it in the node's own process
    (:class:`~pdsmc_ros.controller.action.ControllerView`): lockstep, or an arm a goal process cannot rebuild."""

    def __init__(self, controller: ControllerNode) -> None:
        node = controller.node
        self.controller = controller
        self.core = controller.core
        self.name, self.namespace, self.base = node.get_name(), node.get_namespace(), node.get_fully_qualified_name()
        self.context = node.context
        self.logger = node.get_logger()
        self.robot = controller.core.spec.robot
        self.joints = controller.params.joints
        self.joint_map = controller.joint_map
        self.action_introspection = controller.params.action_introspection
        self.lockstep = controller.lockstep

    @property
    def active(self) -> bool:
        return self.controller.active

    def now(self) -> float:
        return self.controller.now()

    def resolve(self, topic: str) -> str:
        return self.controller.node.resolve_topic_name(topic)

    def check_goal(self, stamp: float, names: Sequence[str], points: Sequence[RawPoint], effort_sizes: Sequence[int],
                   now: float, path: Sequence[Tolerance], goal: Sequence[Tolerance], goal_time: float) -> GoalStart:
        return self.core.check_goal(stamp, names, points, effort_sizes, now, path, goal, goal_time)

    def check_topic_trajectory(self, stamp: float, names: Sequence[str], points: Sequence[RawPoint],
                               effort_sizes: Sequence[int], times: Times, now: float
                               ) -> tuple[JointTrajectoryReference | None, str]:
        return self.core.check_topic_trajectory(stamp, names, points, effort_sizes, times, now)

    def start_goal(self, key: bytes, execution: GoalExecution) -> bool:
        return self.core.start_goal(execution)

    def cancel_goal(self, key: bytes, execution: GoalExecution) -> bool:
        return self.core.goals.cancel(execution)

    def follow(self, reference: JointTrajectoryReference) -> bool:
        return self.core.follow(reference)

    def driving(self) -> JointTrajectoryReference | None:
        driving = self.core.pairing if self.lockstep else self.core.latest
        trajectory = driving.trajectory if driving.source == "trajectory" else None
        return trajectory if isinstance(trajectory, JointTrajectoryReference) else None

    def latest(self) -> tuple[tuple[object, ...] | None, int]:
        return self.core.snapshot, self.controller.guard.clamped


def main(args: Sequence[str] | None = None) -> int:
    return run_node("controller", ControllerNode, args)


if __name__ == "__main__":
    sys.exit(main())
