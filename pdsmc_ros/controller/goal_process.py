"""Real time: the controller's action server in a process of its own, handing the loop validated goals.

A Python control loop shares its process's interpreter lock with every other thread there. The
action server -- rclpy's goal, cancel and result services, each goal's status and feedback, the
conversion of a goal's message (a 5,000-point goal held the lock for 11 ms), the validation --
is Python beside the loop; ``bench/storm.py`` measured the loop's p99 lateness 4.5 times its
idle value under a storm of goals alone with the server in the loop's process. ros2_control keeps
such work off its real-time thread with threads and lock-free buffers; without a free-threaded
interpreter, the equivalent here is a process.

So a real-time controller runs :class:`~.action.FollowJointTrajectoryServer` (the action,
``~/query_state``, ``~/controller_state``'s messages and the goals' feedback) and its parameter
services (:class:`ParameterStandIn`) in a child (``python -m
pdsmc_ros.controller.goal_process``, started with the node at normal scheduling), on a stand-in
of the controller (:class:`RemoteView`) that validates goals and trajectories as the controller
would (:func:`~.core.check_goal`, :func:`~.core.check_topic_trajectory`, from the controller's
latest measured state, asked of the loop's process when a goal arrives) and sends what it
accepts to the loop's process over a pipe.
``~/joint_trajectory`` is read by the controller's process (as bytes, taken with its other inputs:
:meth:`GoalProcess.forward`) and validated here: a reader in the child's own DDS participant
missed one-shot messages that clients sent as soon as they counted the subscription. For the
same reason the goal events and ``~/controller_state`` are serialized here and published by the
controller's process (:data:`PUBLISHED_HERE`): a recorder has matched that participant's writers.
The loop (:class:`GoalProcess`, in its spare time: :meth:`GoalProcess.poll`) starts, follows
and cancels them with the same :class:`~.goals.GoalSlot` as ever, and answers with each goal's
end, the trajectory that drives, its latest period and the goals' feedback at
:data:`~.action.FEEDBACK_HZ`. Its pipes are non-blocking: the loop never waits for the child.
Messages are length-prefixed pickles; a trajectory's points travel as stacked arrays
(:meth:`~.joint_trajectory.JointTrajectoryReference.__getstate__`). The node waits for the child
to serve the action before it activates (:meth:`GoalProcess.wait_ready`): as
joint_trajectory_controller's, the action exists once the controller is active.

Lockstep controllers, which have no deadline, and arms a child cannot rebuild (a robot class
defined where it cannot be imported) keep the server in the controller's process.
"""

from __future__ import annotations

import collections
import contextlib
import fcntl
import os
import pickle
import queue
import select
import signal
import struct
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Mapping, Sequence
from typing import Any

from ..parameters.joint_map import JointMap
from ..robots.registry import find_robot, register_robot, robot_config
from .goals import INVALID_GOAL, GoalExecution, GoalSettings, Outcome
from .joint_trajectory import JointTrajectoryReference, RawPoint
from .limits import JointLimits

FRAME = struct.Struct("<I")  # a message's length before it
PIPE_SIZE = 1 << 20  # bytes: a 5,000-point goal in one pipe's buffer (Linux: fs.pipe-max-size, 1 MiB by default)
READ_CHUNK = 1 << 20
STATE_BACKLOG = 1 << 16  # bytes: the loop drops a state message while this much waits to be written
MEASURE_WAIT_S = 1.0  # the child waits this long for the loop's latest state when a goal arrives
KEPT_TRAJECTORIES = 64  # trajectories remembered for ~/query_state and the driving one
NOT_ACTIVE = Outcome("aborted", INVALID_GOAL, "the controller is not active")
PUBLISHED_HERE = ("goal_event", "controller_state")
"""What the child serializes and the controller's process publishes: the action's goal events and
``~/controller_state`` (one-shot or first messages a recorder must not miss: a writer in the child's
own participant lost a recorder's first ones)."""


class FrameReader:
    """Length-prefixed pickles from a file descriptor (non-blocking in the loop's process)."""

    def __init__(self, fd: int) -> None:
        self.fd = fd
        self.buffer = bytearray()
        self.closed = False

    def read(self) -> list[object]:
        """Every complete message waiting now (a non-blocking descriptor: never waits)."""
        while True:
            try:
                chunk = os.read(self.fd, READ_CHUNK)
            except BlockingIOError:
                break
            except OSError:
                self.closed = True
                break
            if not chunk:
                self.closed = True
                break
            self.buffer += chunk
            if len(chunk) < READ_CHUNK:
                break
        return self._messages()

    def read_blocking(self) -> list[object]:
        """At least one message, or [] at the end of the input (a blocking descriptor)."""
        while not self.closed:
            messages = self._messages()
            if messages:
                return messages
            try:
                chunk = os.read(self.fd, READ_CHUNK)
            except OSError:
                chunk = b""
            if not chunk:
                self.closed = True
            self.buffer += chunk
        return self._messages()

    def _messages(self) -> list[object]:
        messages: list[object] = []
        buffer, start = self.buffer, 0
        while len(buffer) - start >= FRAME.size:
            (size,) = FRAME.unpack_from(buffer, start)
            end = start + FRAME.size + size
            if len(buffer) < end:
                break
            messages.append(pickle.loads(memoryview(buffer)[start + FRAME.size:end]))
            start = end
        if start:
            del buffer[:start]
        return messages


class FrameWriter:
    """Length-prefixed pickles to a non-blocking file descriptor: what does not fit waits for :meth:`flush`."""

    def __init__(self, fd: int) -> None:
        self.fd = fd
        self.pending = bytearray()
        self.closed = False

    def send(self, message: object, *, droppable: bool = False) -> None:
        """Queue ``message`` and write what the pipe takes; a ``droppable`` one is dropped while a
        backlog waits (the child is slow: the next state message says the same, newer)."""
        if self.closed or (droppable and len(self.pending) > STATE_BACKLOG):
            return
        data = pickle.dumps(message, protocol=pickle.HIGHEST_PROTOCOL)
        self.pending += FRAME.pack(len(data))
        self.pending += data
        self.flush()

    def flush(self) -> None:
        while self.pending and not self.closed:
            try:
                written = os.write(self.fd, self.pending)
            except BlockingIOError:
                return
            except OSError:
                self.closed = True
                return
            del self.pending[:written]


def _grow(fd: int) -> None:
    with contextlib.suppress(OSError, AttributeError):
        fcntl.fcntl(fd, fcntl.F_SETPIPE_SZ, PIPE_SIZE)


class GoalProcess:
    """The loop's side of the goal process: it starts the child, and in the loop's spare time
    (:meth:`poll`) drives what the child accepted and tells it how goals end.

    Parameters
    ----------
    setup : dict
        What the child needs to stand in for the controller (:func:`setup_of`).
    core : ControllerCore
        The controller's decisions: its goal slot, trajectories and latest period.
    clamped : callable
        The number of periods the torque was clamped so far.
    active : bool
        Whether the controller commands now (:meth:`set_active` from then on).
    on_lost : callable
        ``on_lost(why)``: told once if the child ends before :meth:`close` (the action is gone).
    publishers : mapping
        By kind (:data:`PUBLISHED_HERE`), what publishes the child's serialized messages of that
        kind in this process: what a recorder or a client meets as a topic stays in the participant
        it already discovered.
    on_gains : callable
        ``on_gains(gains, given)``: gains the child accepted through the controller's parameter
        services (resolved from the gain parameters ``given``), for the loop to apply.
    """

    def __init__(self, setup: dict[str, Any], core: Any, clamped: Callable[[], int], *, active: bool = False,
                 on_lost: Callable[[str], None] = lambda why: None,
                 publishers: Mapping[str, Callable[[bytes], None]] | None = None,
                 on_gains: Callable[[Any, dict[str, Any]], None] | None = None) -> None:
        self.first_message = pickle.dumps(setup, protocol=pickle.HIGHEST_PROTOCOL)
        self.core = core
        self.clamped = clamped
        self.active = active
        self.on_lost = on_lost
        self.publishers = dict(publishers or {})
        self.on_gains = on_gains
        self.lost = False
        self.process: subprocess.Popen[bytes] | None = None
        self.reader: FrameReader | None = None
        self.writer: FrameWriter | None = None
        self.notices: collections.deque[object] = collections.deque()  # from other threads, sent by poll
        self.goals: dict[bytes, GoalExecution] = {}  # started here, their end not yet told
        self.ids: collections.OrderedDict[int, tuple[JointTrajectoryReference, object]] = collections.OrderedDict()
        self.told_driving: object = None
        self.ready = False
        self.next_state = 0.0
        self.period_s = 1.0 / _feedback_hz()

    @classmethod
    def for_controller(cls, setup: dict[str, Any], core: Any, clamped: Callable[[], int],
                       on_lost: Callable[[str], None], publishers: Mapping[str, Callable[[bytes], None]],
                       on_gains: Callable[[Any, dict[str, Any]], None]) -> GoalProcess | None:
        """A goal process, or None when the arm cannot be sent to one (a robot class defined where a
        child cannot import it): the caller then serves the action and the parameters in its own process."""
        try:
            return cls(setup, core, clamped, on_lost=on_lost, publishers=publishers, on_gains=on_gains)
        except (pickle.PicklingError, AttributeError, TypeError):
            return None

    def start(self) -> None:
        """Start the child (from the node's thread, at normal scheduling, before the loop runs)."""
        # stdout is the child's messages; its stderr is the node's (its log lines)
        self.process = subprocess.Popen([sys.executable, "-m", __name__], stdin=subprocess.PIPE,
                                        stdout=subprocess.PIPE)
        if self.process.stdin is None or self.process.stdout is None:  # pragma: no cover - started with pipes
            raise OSError("no pipes to the goal process")
        to_child, from_child = self.process.stdin.fileno(), self.process.stdout.fileno()
        _grow(to_child)
        _grow(from_child)
        self.process.stdin.write(FRAME.pack(len(self.first_message)) + self.first_message)
        self.process.stdin.flush()
        os.set_blocking(to_child, False)
        os.set_blocking(from_child, False)
        self.reader, self.writer = FrameReader(from_child), FrameWriter(to_child)

    def wait_ready(self, timeout_s: float) -> bool:
        """Wait (the node's thread, before the loop runs) until the child serves the action, its
        topic and its services -- as joint_trajectory_controller's exist once it is active --
        for up to ``timeout_s``; whether it does."""
        reader = self.reader
        if reader is None:
            return False
        deadline = time.monotonic() + timeout_s
        while not self.ready and not reader.closed:
            left = deadline - time.monotonic()
            if left <= 0.0:
                return False
            select.select([reader.fd], [], [], left)
            for message in reader.read():
                if message == ("ready",):
                    self.ready = True
                else:  # pragma: no cover - the child sends nothing before it is ready
                    self._carry_out(message)
        return self.ready

    def forward(self, batch: list[tuple[bytes, tuple[float | None, float | None]]]) -> None:
        """``~/joint_trajectory`` messages taken by the controller's process (serialized, with the
        middleware's sent and received times), for the child to validate: the topic's reader stays
        in the participant a client already discovered (a reader in the child's own participant
        missed one-shot messages a client sent as soon as it counted the subscription)."""
        if self.writer is not None:
            for data, times in batch:
                self.writer.send(("trajectory", bytes(data), times))

    def set_active(self, active: bool) -> None:
        """The controller was activated or deactivated (any thread): told to the child by :meth:`poll`."""
        self.active = active
        self.notices.append(("active", active))

    def tell_runaway(self, reason: str) -> None:
        """The runaway stop latched (``reason``) or was reset (""): told to the child by :meth:`poll`."""
        self.notices.append(("runaway", reason))

    # -- the loop's side -------------------------------------------------------- #
    def poll(self, now: float) -> None:
        """The loop's spare time at ``now`` (``perf_counter``): the child's requests carried out,
        each goal's end, the driving trajectory and (at the feedback rate) the latest period told."""
        reader, writer = self.reader, self.writer
        if reader is None or writer is None:
            return
        for message in reader.read():
            self._carry_out(message)
        if (reader.closed or writer.closed) and not self.lost:
            self.lost = True
            code = self.process.poll() if self.process is not None else None
            self.on_lost(f"the goal process ended (exit status {code}): no FollowJointTrajectory server, "
                         "~/joint_trajectory or ~/query_state until the controller restarts")
        while self.notices:
            writer.send(self.notices.popleft())
        for key, execution in list(self.goals.items()):
            if execution.outcome is not None:
                writer.send(("ended", key, execution.outcome))
                del self.goals[key]
        driving = self._driving()
        if driving != self.told_driving:
            self.told_driving = driving
            writer.send(("driving", *driving) if driving is not None else ("driving", None, 0.0, 0.0))
        if now >= self.next_state:
            self.next_state = max(self.next_state + self.period_s, now)
            feedback = {key: execution.feedback for key, execution in self.goals.items()
                        if execution.feedback is not None}
            writer.send(("state", self.core.snapshot, self.clamped(), feedback), droppable=True)
        writer.flush()

    def _carry_out(self, message: Any) -> None:
        kind = message[0]
        core = self.core
        if kind == "start":
            _, key, execution = message
            self.goals[key] = execution
            if not self.active:
                execution.finish(NOT_ACTIVE)
                return
            self._remember(execution.reference, key)
            core.start_goal(execution)
        elif kind == "follow":
            _, tid, reference = message
            if self.active:
                self._remember(reference, tid)
                core.follow(reference)
        elif kind == "publish":
            publish = self.publishers.get(message[1])
            if publish is not None:
                publish(message[2])
        elif kind == "gains":
            if self.on_gains is not None:
                self.on_gains(message[1], message[2])
        elif kind == "measure":
            if self.writer is not None:
                self.writer.send(("measured", core.measured()))
        elif kind == "cancel":
            execution = self.goals.get(message[1])
            if execution is not None:
                core.goals.cancel(execution)

    def _remember(self, reference: JointTrajectoryReference, tid: object) -> None:
        self.ids[id(reference)] = (reference, tid)  # the reference kept: its id is not reused meanwhile
        while len(self.ids) > KEPT_TRAJECTORIES:
            self.ids.popitem(last=False)

    def _driving(self) -> tuple[object, float, float] | None:
        latest = self.core.latest
        trajectory = latest.trajectory if latest.source == "trajectory" else None
        entry = self.ids.get(id(trajectory))
        if entry is None or entry[0] is not trajectory:
            return None
        return entry[1], trajectory.start_time, trajectory.end_time  # type: ignore[union-attr]

    def close(self) -> None:
        """End the child (it ends its goals: the controller is stopping)."""
        process, self.process = self.process, None
        if process is None:
            return
        for pipe in (process.stdin, process.stdout):
            if pipe is not None:
                with contextlib.suppress(OSError):
                    pipe.close()
        try:
            process.wait(timeout=3.0)
        except subprocess.TimeoutExpired:
            process.kill()
            with contextlib.suppress(subprocess.TimeoutExpired):
                process.wait(timeout=3.0)


def _feedback_hz() -> float:
    from .action import FEEDBACK_HZ  # the action module imports rclpy: only where a node runs

    return FEEDBACK_HZ


def setup_of(*, spec: Any, name: str, namespace: str, base: str, joints: Sequence[str], joint_map: JointMap,
             robot_joints: Sequence[str], limits: JointLimits | None, goal_settings: GoalSettings,
             action_introspection: str, topics: dict[str, str], use_sim_time: bool,
             parameters: Sequence[tuple[bytes, bytes]] = (), stability: dict[str, Any] | None = None
             ) -> dict[str, Any]:
    """What the child needs to stand in for the controller: its names, joints, checks and the arm
    as registered in this process (a URDF arm named, given as a path or received on
    ``/robot_description`` is registered in-process); ``parameters`` (:func:`parameter_table`) and
    ``stability`` (the gains' stability check's keywords) for its parameter services, none without."""
    return {"spec": spec, "arm": find_robot(spec.robot), "config": dict(robot_config(spec.robot)), "name": name,
            "namespace": namespace, "base": base, "joints": tuple(joints), "joint_map": joint_map,
            "robot_joints": tuple(robot_joints), "limits": limits, "goal_settings": goal_settings,
            "action_introspection": action_introspection, "topics": dict(topics), "use_sim_time": use_sim_time,
            "parameters": list(parameters), "stability": stability}


def parameter_table(node: Any) -> list[tuple[bytes, bytes]]:
    """Every parameter ``node`` declared, as its value and its descriptor (both serialized), for
    the child to declare the same (unset ones included: their type is in the descriptor)."""
    from rclpy.serialization import serialize_message

    return [(serialize_message(parameter.to_parameter_msg()), serialize_message(node.describe_parameter(name)))
            for name, parameter in node._parameters.items()]  # noqa: SLF001 - unset typed ones too


# --------------------------------------------------------------------------- #
# The child
# --------------------------------------------------------------------------- #
class RemoteView:
    """The controller as the action server sees it in the goal process
    (:class:`~.action.ControllerView`): goals validated here, carried out by the loop's process."""

    def __init__(self, setup: dict[str, Any], context: Any, send: Callable[[object], None]) -> None:
        import rclpy.logging

        from .joints import JointSelector

        self.name, self.namespace, self.base = setup["name"], setup["namespace"], setup["base"]
        self.context = context
        self.logger = rclpy.logging.get_logger(self.name)
        self.robot = setup["spec"].robot
        self.joints = setup["joints"]
        self.joint_map = setup["joint_map"]
        self.action_introspection = setup["action_introspection"]
        self.lockstep = False
        self.active = False
        self.topics = setup["topics"]
        self.limits: JointLimits | None = setup["limits"]
        self.settings: GoalSettings = setup["goal_settings"]
        self.selector = JointSelector(setup["robot_joints"])
        self.send = send
        self.latched = ""  # the runaway stop's reason while latched
        self.snapshot: tuple[Any, ...] | None = None
        self.clamped = 0
        self.started: dict[bytes, GoalExecution] = {}  # sent to the loop, their end not yet known
        self.trajectories: collections.OrderedDict[object, JointTrajectoryReference] = collections.OrderedDict()
        self.driving_now: tuple[object, float, float] | None = None
        self.topic_count = 0
        self.clock: Any = None  # the action server's node's (its use_sim_time is the controller's)
        self.asking = threading.Lock()
        self.answered = threading.Event()
        self.answer: tuple[Any, Any] | None = None
        self.lock = threading.Lock()  # the executor's threads and the reader thread

    def now(self) -> float:
        return self.clock.now().nanoseconds * 1e-9

    def resolve(self, topic: str) -> str:
        return self.topics[topic]

    def measured(self) -> tuple[Any, Any] | None:
        """The controller's latest complete measured state ``(q, qd)`` (robot order), asked of the
        loop's process -- the very state its own checks would use, as joint_trajectory_controller's
        -- or, if it does not answer within :data:`MEASURE_WAIT_S` (a loop with no spare time), the
        one of its latest period; None before the first."""
        with self.asking:  # one question at a time (the executor's threads)
            self.answered.clear()
            self.send(("measure",))
            if self.answered.wait(MEASURE_WAIT_S):
                return self.answer
            snapshot = self.snapshot
            return None if snapshot is None else (snapshot[1], snapshot[2])

    def check_goal(self, stamp: float, names: Sequence[str], points: Sequence[RawPoint], effort_sizes: Sequence[int],
                   now: float, path: Sequence[Any], goal: Sequence[Any], goal_time: float) -> Any:
        from .core import check_goal

        return check_goal(self.settings, self.limits, self.selector.joints, self.measured(), self.latched_reason(),
                          stamp, names, points, effort_sizes, now, path, goal, goal_time)

    def check_topic_trajectory(self, stamp: float, names: Sequence[str], points: Sequence[RawPoint],
                               effort_sizes: Sequence[int], times: Any, now: float
                               ) -> tuple[JointTrajectoryReference | None, str]:
        from .core import check_topic_trajectory

        return check_topic_trajectory(self.settings, self.limits, self.selector.joints, self.measured(),
                                      self.latched_reason(), False, stamp, names, points, effort_sizes, times, now)

    def latched_reason(self) -> str:
        from .core import latched_refusal

        return latched_refusal(self.latched)

    def _running_goal(self) -> bool:
        return any(execution.outcome is None for execution in self.started.values())

    def start_goal(self, key: bytes, execution: GoalExecution) -> bool:
        with self.lock:
            preempts = self._running_goal()
            self.started[key] = execution
            self._remember(key, execution.reference)
        self.send(("start", key, execution))
        return preempts

    def cancel_goal(self, key: bytes, execution: GoalExecution) -> bool:
        if execution.outcome is not None:
            return False
        self.send(("cancel", key))
        return True

    def follow(self, reference: JointTrajectoryReference) -> bool:
        with self.lock:
            self.topic_count += 1
            tid = self.topic_count
            self._remember(tid, reference)
            goes_on = self._running_goal()
        self.send(("follow", tid, reference))
        return goes_on

    def _remember(self, tid: object, reference: JointTrajectoryReference) -> None:
        self.trajectories[tid] = reference
        while len(self.trajectories) > KEPT_TRAJECTORIES:
            self.trajectories.popitem(last=False)

    def driving(self) -> JointTrajectoryReference | None:
        with self.lock:
            if self.driving_now is None:
                return None
            tid, start, end = self.driving_now
            reference = self.trajectories.get(tid)
            if reference is not None:  # the loop starts a goal stamped 0 at its first sample of it
                reference.start_time, reference.end_time = start, end
            return reference

    def latest(self) -> tuple[tuple[Any, ...] | None, int]:
        return self.snapshot, self.clamped

    def hear(self, message: Any) -> bool:
        """A message from the loop's process; whether the state publisher has news to send."""
        kind = message[0]
        if kind == "active":
            self.active = bool(message[1])
        elif kind == "runaway":
            self.latched = str(message[1])
        elif kind == "ended":
            with self.lock:
                execution = self.started.pop(message[1], None)
            if execution is not None:
                execution.finish(message[2])
        elif kind == "measured":
            self.answer = message[1]
            self.answered.set()
        elif kind == "driving":
            with self.lock:
                self.driving_now = None if message[1] is None else (message[1], message[2], message[3])
        elif kind == "state":
            _, self.snapshot, self.clamped, feedback = message
            with self.lock:
                for key, value in feedback.items():
                    execution = self.started.get(key)
                    if execution is not None:
                        execution.feedback = value
            return True
        return False


class ParameterStandIn:
    """The controller's parameter services (``/<controller>/get_parameters``, ``set_parameters``,
    ...), served in the goal process on a node of its own that declares the controller's
    parameters as they are (:func:`parameter_table`) and guards them with the controller's own
    callbacks: the tables' checks (:func:`~pdsmc_ros.ros.node_run.guard_run_parameters`; rclpy
    refuses read-only ones and wrong types from their descriptors) and the gains' resolver and
    stability check (:class:`~.parameters.GainUpdates`, here in this process). Gains it accepts
    are sent to the loop's process (``("gains", gains, given)``), which applies them in its spare
    time. ``ros2 param set`` at ten sets a second held the loop's interpreter lock 1-3 ms a set
    (rclpy's conversions, the callbacks) and kept the loop's p99 lateness at 1.5-2.2 times idle.

    Events on ``/parameter_events`` name the controller, as its own would.
    """

    def __init__(self, setup: dict[str, Any], context: Any, send: Callable[[object], None]) -> None:
        from rcl_interfaces.msg import Parameter as ParameterMsg
        from rcl_interfaces.msg import ParameterDescriptor
        from rclpy.parameter import Parameter
        from rclpy.parameter_service import ParameterService
        from rclpy.serialization import deserialize_message

        from ..control.stability import check_rate
        from ..ros.node_run import guard_run_parameters
        from .parameters import GainUpdates

        table = [(Parameter.from_parameter_msg(deserialize_message(value, ParameterMsg)),
                  deserialize_message(descriptor, ParameterDescriptor)) for value, descriptor in setup["parameters"]]
        self.node = node = _stand_in_node(
            setup["base"], f"{setup['name']}_parameters", namespace=setup["namespace"], context=context,
            use_global_arguments=False, start_parameter_services=False, enable_rosout=False,
            parameter_overrides=[p for p, _ in table if p.type_ != Parameter.Type.NOT_SET])
        for parameter, descriptor in table:
            if not node.has_parameter(parameter.name):
                unset = parameter.type_ == Parameter.Type.NOT_SET and descriptor.type != Parameter.Type.NOT_SET
                node.declare_parameter(parameter.name, Parameter.Type(descriptor.type) if unset else parameter.value,
                                       descriptor)
        node._parameter_event_publisher.on = True  # noqa: SLF001 - the controller announced its declarations
        spec = setup["spec"]
        guard_run_parameters(node, spec.controller, gains=True)
        reference, stability = spec.reference(), setup["stability"] or {}
        self.gains = GainUpdates(node, spec, lambda new: check_rate(new, reference, **stability),
                                 lambda gains: send(("gains", gains, self.gains.given)),
                                 joint_map=setup["joint_map"])
        self.named = _Named(node, setup["name"])  # ParameterService keeps a weak reference to it
        self.service = ParameterService(self.named)

    def destroy(self) -> None:
        self.node.destroy_node()


def _stand_in_node(base: str, *args: Any, **kwargs: Any) -> Any:
    """An rclpy Node whose ``/parameter_events`` name the controller ``base``, silent until its
    writer's ``on`` is set: rclpy's own declarations in ``Node.__init__`` (``use_sim_time``) and
    the stand-in's are the controller's, which it announced itself."""
    from rclpy.node import Node

    class StandInNode(Node):
        @property
        def _parameter_event_publisher(self) -> Any:
            return self._events_as

        @_parameter_event_publisher.setter
        def _parameter_event_publisher(self, publisher: Any) -> None:  # rclpy's writer, then None at destruction
            self._events_as = None if publisher is None else _EventsAs(publisher, base)

    return StandInNode(*args, **kwargs)


class _EventsAs:
    """rclpy's ``/parameter_events`` writer of a stand-in node: its events name ``node`` (from :attr:`on`)."""

    def __init__(self, publisher: Any, node: str) -> None:
        self.publisher = publisher
        self.node = node
        self.on = False

    def publish(self, event: Any) -> None:
        if self.on:
            event.node = self.node
            self.publisher.publish(event)


class _Named:
    """``node`` as rclpy's ParameterService sees it: its services named after ``name``."""

    def __init__(self, node: Any, name: str) -> None:
        self._node = node
        self._name = name

    def get_name(self) -> str:
        return self._name

    def __getattr__(self, attribute: str) -> Any:
        return getattr(self._node, attribute)


def main() -> None:
    """The child: the setup first, then the loop's messages until its input closes."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # a Ctrl-C to the group is the parent's to handle
    with contextlib.suppress(OSError, AttributeError):  # never a real-time policy inherited from a loop thread
        os.sched_setscheduler(0, os.SCHED_OTHER, os.sched_param(0))
    inbox = FrameReader(sys.stdin.fileno())
    first = inbox.read_blocking()
    if not first:
        return
    setup: dict[str, Any] = first.pop(0)  # type: ignore[assignment]
    spec = setup["spec"]
    if setup["arm"] is not None and find_robot(spec.robot) is None:
        register_robot(setup["arm"], config=setup["config"])

    import rclpy
    from rclpy.parameter import Parameter
    from rclpy.serialization import deserialize_message
    from rclpy.signals import SignalHandlerOptions
    from trajectory_msgs.msg import JointTrajectory

    from ..ros.topics import TOPIC_JOINT_TRAJECTORY
    from .action import FollowJointTrajectoryServer, topic_trajectory

    context = rclpy.Context()
    rclpy.init(args=[], context=context, signal_handler_options=SignalHandlerOptions.NO)
    out = sys.stdout.fileno()
    write_lock = threading.Lock()

    def send(message: object) -> None:
        data = pickle.dumps(message, protocol=pickle.HIGHEST_PROTOCOL)
        with write_lock, contextlib.suppress(OSError):  # the loop's process gone: it ends this one too
            _write_all(out, FRAME.pack(len(data)) + data)

    view = RemoteView(setup, context, send)
    overrides = [Parameter("use_sim_time", value=bool(setup["use_sim_time"]))]
    server = FollowJointTrajectoryServer(view, parameter_overrides=overrides, takes_topic=False,
                                         event_sink=lambda data: send(("publish", "goal_event", data)),
                                         state_sink=lambda data: send(("publish", "controller_state", data)))
    view.clock = server.node.get_clock()
    parameters = ParameterStandIn(setup, context, send) if setup["parameters"] else None
    if parameters is not None:
        server.executor.add_node(parameters.node)
    # ~/joint_trajectory messages, in order, in a thread of their own: their validation asks the
    # loop's process for its state, which this (reading) thread receives
    trajectories: queue.Queue[Any] = queue.Queue()

    def take_trajectories() -> None:
        while (item := trajectories.get()) is not None:
            data, times = item
            try:
                msg = deserialize_message(data, JointTrajectory)
            except Exception as exc:  # noqa: BLE001 - any malformed message: refused, never fatal
                server.report.report("error", f"{view.resolve(TOPIC_JOINT_TRAJECTORY)}: malformed message ({exc})")
                continue
            topic_trajectory(view, msg, times, server.report)

    worker = threading.Thread(target=take_trajectories, name="joint_trajectory", daemon=True)
    worker.start()
    send(("ready",))
    try:
        for message in first:
            view.hear(message)
        while True:
            messages = inbox.read_blocking()
            if not messages:
                break  # the controller's process is gone or stopping
            news = False
            for message in messages:
                if message[0] == "trajectory":  # type: ignore[index]
                    trajectories.put(message[1:])  # type: ignore[index]
                    continue
                news = view.hear(message) or news
            if news:
                server.state.send(float("inf"), list(server.goals.values()))
    finally:
        trajectories.put(None)
        worker.join(timeout=2.0)
        server.stop()
        if parameters is not None:
            parameters.destroy()
        with contextlib.suppress(Exception):
            rclpy.shutdown(context=context)


def _write_all(fd: int, data: bytes) -> None:
    view = memoryview(data)
    while view:
        written = os.write(fd, view)
        view = view[written:]


if __name__ == "__main__":
    main()
