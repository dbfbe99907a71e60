"""Real time: the loop's side of the goal process, the controller's action server in a process of its own.

A Python control loop shares its process's interpreter lock with every other thread there. The
action server -- rclpy's goal, cancel and result services, each goal's status and feedback, the
conversion of a goal's message (a 5,000-point goal held the lock for 11 ms), the validation --
is Python beside the loop; ``bench/storm/`` measured the loop's p99 lateness 4.5 times its
idle value under a storm of goals alone with the server in the loop's process. ros2_control keeps
such work off its real-time thread with threads and lock-free buffers; without a free-threaded
interpreter, the equivalent here is a process.

So a real-time controller runs :class:`~pdsmc_ros.controller.action.FollowJointTrajectoryServer`
(the action, ``~/query_state``, ``~/controller_state``'s messages and the goals' feedback) and its
parameter services (:class:`~.parameter_stand_in.ParameterStandIn`) in a child (``python -m
pdsmc_ros.controller.sidecar.goal_child``, :mod:`.goal_child`, started with the node at normal
scheduling), on a stand-in of the controller (:class:`~.remote_view.RemoteView`) that validates
goals and trajectories as the controller would (:func:`~pdsmc_ros.controller.core.check_goal`,
:func:`~pdsmc_ros.controller.core.check_topic_trajectory`, from the controller's latest measured
state, asked of the loop's process when a goal arrives) and sends what it accepts to the loop's
process over a pipe.
``~/joint_trajectory`` is read by the controller's process (as bytes, taken with its other inputs:
:meth:`GoalProcess.forward`) and validated there: a reader in the child's own DDS participant
missed one-shot messages that clients sent as soon as they counted the subscription. For the
same reason the goal events and ``~/controller_state`` are serialized in the child and published by
the controller's process (:data:`PUBLISHED_HERE`): a recorder has matched that participant's writers.
The loop (:class:`GoalProcess`, here, in its spare time: :meth:`GoalProcess.poll`) starts, follows
and cancels them with the same :class:`~pdsmc_ros.controller.goals.GoalSlot` as ever, and answers
with each goal's end, the trajectory that drives, its latest period and the goals' feedback at
:data:`~pdsmc_ros.controller.action.FEEDBACK_HZ`. Its pipes are non-blocking: the loop never waits
for the child. Messages are :mod:`.framing`'s frames; a trajectory's points travel as stacked arrays
(:meth:`~pdsmc_ros.controller.joint_trajectory.JointTrajectoryReference.__getstate__`). The node
waits for the child to serve the action before it activates (:meth:`GoalProcess.wait_ready`): as
joint_trajectory_controller's, the action exists once the controller is active. The child's life
(started, watched, replaced by a spare) is :mod:`.process`'s.

Lockstep controllers, which have no deadline, and arms a child cannot rebuild (a robot class
defined where it cannot be imported) keep the server in the controller's process.
"""

from __future__ import annotations

import collections
import contextlib
import os
import pickle
import select
import subprocess
import threading
import time
from collections.abc import Callable, Mapping, Sequence
from typing import Any

from ...parameters.joint_map import JointMap
from ...robots.registry import find_robot, robot_config
from ..goals import INVALID_GOAL, GoalExecution, GoalSettings, Outcome
from ..joint_trajectory import JointTrajectoryReference
from ..limits import JointLimits
from .framing import FrameReader, FrameWriter, frame
from .process import Spare, end, how_it_ended, kill, spawn, stopped

CHILD = "pdsmc_ros.controller.sidecar.goal_child"
"""The child's module (``python -m``)."""
KEPT_TRAJECTORIES = 64  # trajectories remembered for ~/query_state and the driving one (both sides)
NOT_ACTIVE = Outcome("aborted", INVALID_GOAL, "the controller is not active")
WATCH_S = 0.1  # how often the watching thread looks whether the child is stopped
RESTART_WAIT_S = 30.0  # how long a new child may take to serve (its interpreter, rclpy, the arm)
PUBLISHED_HERE = ("goal_event", "controller_state")
"""What the child serializes and the controller's process publishes: the action's goal events and
``~/controller_state`` (one-shot or first messages a recorder must not miss: a writer in the child's
own participant lost a recorder's first ones)."""


GOAL_PROCESS_CORES = 2
"""``goal_process:=auto`` runs the goal process when the controller's process may run on this many
cores or more. On 2 cores it costs the ordinary run nothing measurable and keeps a storm of clients
off the loop (``bench/ordinary_run.py``, ``bench/storm/``: docs/PERFORMANCE.md); on one core the
child could only take the loop's own core."""


def uses_goal_process(choice: str, cores: int | None = None) -> bool:
    """Whether a real-time controller serves its action and parameters from a goal process:
    ``choice`` ``always``, ``never`` or ``auto`` (a goal process with at least :data:`GOAL_PROCESS_CORES` of the
    ``cores`` this process may run on: by default its CPU affinity's)."""
    if choice not in ("auto", "always", "never"):
        raise ValueError(f"goal_process must be auto, always or never, got {choice!r}")
    if choice != "auto":
        return choice == "always"
    return (len(os.sched_getaffinity(0)) if cores is None else cores) >= GOAL_PROCESS_CORES


class GoalProcess:
    """The loop's side of the goal process: it starts the child, and in the loop's spare time
    (:meth:`poll`) drives what the child accepted and tells it how goals end.

    A child that ends (killed, crashed) or stops (``SIGSTOP``: it would answer nothing again) is
    replaced: the goal it served ends aborted in the loop, which holds the arm, and a new child,
    started by a watching thread of normal scheduling, serves the action, ``~/joint_trajectory``
    and the parameter services again (the parameters as they are now, gains changed through the
    old child included).

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
        ``on_lost(why)``: told from the loop's thread when the child ended before :meth:`close`.
    on_restored : callable
        ``on_restored(what)``: told from the watching thread when a new child serves again.
    publishers : mapping
        By kind (:data:`PUBLISHED_HERE`), what publishes the child's serialized messages of that
        kind in this process: what a recorder or a client meets as a topic stays in the participant
        it already discovered.
    on_gains : callable
        ``on_gains(gains, given)``: gains the child accepted through the controller's parameter
        services (resolved from the gain parameters ``given``), for the loop to apply.
    parameters_now : callable
        The parameter table (:func:`parameter_table`) a new child starts from.
    results : LostResults, optional
        The action's ``get_result`` service in this process (:class:`~.lost_results.LostResults`):
        told the outcome of a goal lost with the child, it answers the client that waits for it;
        its requests are gathered by the watching thread.
    """

    def __init__(self, setup: dict[str, Any], core: Any, clamped: Callable[[], int], *, active: bool = False,
                 on_lost: Callable[[str], None] = lambda why: None,
                 on_restored: Callable[[str], None] = lambda what: None,
                 publishers: Mapping[str, Callable[[bytes], None]] | None = None,
                 on_gains: Callable[[Any, dict[str, Any]], None] | None = None,
                 parameters_now: Callable[[], list[tuple[bytes, bytes]]] | None = None,
                 results: Any = None) -> None:
        self.setup = dict(setup)
        self.first_message = frame(setup)
        self.core = core
        self.clamped = clamped
        self.active = active
        self.runaway = ""
        self.on_lost = on_lost
        self.on_restored = on_restored
        self.publishers = dict(publishers or {})
        self.on_gains = on_gains
        self.parameters_now = parameters_now
        self.results = results
        self.lost = False
        self.process: subprocess.Popen[bytes] | None = None
        self.reader: FrameReader | None = None
        self.writer: FrameWriter | None = None
        self.goals: dict[bytes, GoalExecution] = {}  # started here, their end not yet told
        self.ids: collections.OrderedDict[int, tuple[JointTrajectoryReference, object]] = collections.OrderedDict()
        self.told_driving: object = None
        self.ready = False
        self.serving = False  # to serve the action (:meth:`serve`), once there is a state
        self.told_serve = False  # the child was told to serve (a new child is told at once)
        self.next_state = 0.0
        self.period_s = 1.0 / _feedback_hz()
        # the child's pipes change hands under this lock (a new child); the loop never waits for it
        self.swap = threading.Lock()
        self.replace = threading.Event()
        self.closing = False
        self.watcher: threading.Thread | None = None
        self.restarts = 0
        # a child started ahead, its imports done, waiting for a setup: a replacement serves in a fraction
        # of an interpreter's start (0.9-2.8 s here under load)
        self.spare = Spare(CHILD)
        self.stop_seen = False  # the watching thread found the child stopped (SIGSTOP) and killed it

    @classmethod
    def for_controller(cls, setup: dict[str, Any], core: Any, clamped: Callable[[], int], *,
                       on_lost: Callable[[str], None], on_restored: Callable[[str], None],
                       publishers: Mapping[str, Callable[[bytes], None]],
                       on_gains: Callable[[Any, dict[str, Any]], None],
                       parameters_now: Callable[[], list[tuple[bytes, bytes]]],
                       results: Any = None) -> GoalProcess | None:
        """A goal process, or None when the arm cannot be sent to one (a robot class defined where a
        child cannot import it): the caller then serves the action and the parameters in its own process."""
        try:
            return cls(setup, core, clamped, on_lost=on_lost, on_restored=on_restored, publishers=publishers,
                       on_gains=on_gains, parameters_now=parameters_now, results=results)
        except (pickle.PicklingError, AttributeError, TypeError):
            return None

    def start(self) -> None:
        """Start the child and the thread that watches it (from the node's thread, at normal
        scheduling, before the loop runs: both inherit it)."""
        self.process, self.reader, self.writer = self._launch(self.first_message)
        self.watcher = threading.Thread(target=self._watch, name="goal_process_watch", daemon=True)
        self.watcher.start()
        self.replace.set()  # the watching thread starts the spare

    @staticmethod
    def _spawn() -> subprocess.Popen[bytes]:
        """A child that imports what it needs and waits for its setup (no DDS participant until then)."""
        return spawn(CHILD)  # stdout is the child's messages; its stderr is the node's (its log lines)

    @classmethod
    def _launch(cls, first_message: bytes, process: subprocess.Popen[bytes] | None = None
                ) -> tuple[subprocess.Popen[bytes], FrameReader, FrameWriter]:
        """``process`` (a spare, or a new child) given its setup; its pipes' two ends here."""
        process = process or cls._spawn()
        if process.stdin is None or process.stdout is None:  # pragma: no cover - started with pipes
            raise OSError("no pipes to the goal process")
        process.stdin.write(first_message)
        process.stdin.flush()
        to_child, from_child = process.stdin.fileno(), process.stdout.fileno()
        os.set_blocking(to_child, False)
        os.set_blocking(from_child, False)
        return process, FrameReader(from_child), FrameWriter(to_child)

    def _wait_for(self, reader: FrameReader, kind: str, timeout_s: float, carry_out: bool) -> bool:
        """Wait until the child sends ``(kind,)``, up to ``timeout_s``; other messages carried out
        (``carry_out``) or dropped."""
        deadline = time.monotonic() + timeout_s
        while not reader.closed:
            for message in reader.read():
                if message == (kind,):
                    return True
                if carry_out:  # pragma: no cover - the child sends nothing else before it answers
                    self._carry_out(message)
            left = deadline - time.monotonic()
            if left <= 0.0:
                return False
            select.select([reader.fd], [], [], left)
        return False

    def wait_ready(self, timeout_s: float) -> bool:
        """Wait (the node's thread, before the loop runs) until the child serves the parameter
        services, for up to ``timeout_s``; whether it does."""
        if self.reader is None:
            return False
        self.ready = self._wait_for(self.reader, "ready", timeout_s, carry_out=True)
        return self.ready

    def serve(self) -> None:
        """Have the child serve the action, ``~/query_state`` and validate ``~/joint_trajectory`` once
        the controller has a complete measured state (told by :meth:`poll`: a goal starts from it, and a
        client that sees the server must not be refused for want of one); a new child is told too."""
        self.serving = True

    def forward(self, batch: list[tuple[bytes, tuple[float | None, float | None]]]) -> None:
        """``~/joint_trajectory`` messages taken by the controller's process (serialized, with the
        middleware's sent and received times), for the child to validate: the topic's reader stays
        in the participant a client already discovered (a reader in the child's own participant
        missed one-shot messages a client sent as soon as it counted the subscription)."""
        writer = self.writer
        if writer is not None:
            for data, times in batch:
                writer.send(("trajectory", bytes(data), times))

    def set_active(self, active: bool) -> None:
        """The controller was activated or deactivated (any thread): told to the child at once, before
        any goal or trajectory that follows (the loop's spare time may be seconds away at start)."""
        with self.swap:
            self.active = active
            if self.writer is not None:
                self.writer.send(("active", active))

    def tell_runaway(self, reason: str) -> None:
        """The runaway stop latched (``reason``) or was reset (""): told to the child at once."""
        with self.swap:
            self.runaway = reason
            if self.writer is not None:
                self.writer.send(("runaway", reason))

    # -- the loop's side -------------------------------------------------------- #
    def poll(self, now: float) -> None:
        """The loop's spare time at ``now`` (``perf_counter``): the child's requests carried out,
        each goal's end, the driving trajectory and (at the feedback rate) the latest period told."""
        if not self.swap.acquire(blocking=False):  # a new child is being handed over: the next turn
            return
        try:
            self._poll(now)
        finally:
            self.swap.release()

    def _poll(self, now: float) -> None:
        reader, writer = self.reader, self.writer
        if reader is None or writer is None or self.lost:
            return
        for message in reader.read():
            self._carry_out(message)
        if reader.closed or writer.closed:
            self._lose()
            return
        if self.serving and not self.told_serve and self.core.measured() is not None:
            self.told_serve = True
            writer.send(("serve",))
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

    def _lose(self) -> None:
        """The child is gone (the loop's thread): its goal ends aborted and the arm holds; a new
        child is asked of the watching thread."""
        self.lost = True
        code = self.process.poll() if self.process is not None else None
        how = "stopped (SIGSTOP), so killed" if self.stop_seen else how_it_ended(code)
        self.stop_seen = False
        why = f"the goal process ended ({how})"
        ended = {key: execution for key, execution in self.goals.items() if execution.outcome is None}
        aborted = Outcome("aborted", INVALID_GOAL, f"{why}: the goal was aborted")
        if ended and self.core.goals.end(aborted.error_string) is not None:
            self.core.hold(why)
        if self.results is not None:  # its client's result request died with the child: answered from here
            for key, execution in ended.items():
                self.results.lose(key, execution.outcome or aborted)
        self.goals.clear()
        self.on_lost(f"{why}: {'its goal aborted, the arm holds; ' if ended else ''}a new one is starting")
        self.replace.set()

    def _watch(self) -> None:
        """The watching thread: a child stopped (``SIGSTOP``) is killed, which the loop then sees as
        an ended child; an ended child is replaced."""
        while not self.closing:
            if self.replace.wait(WATCH_S):
                self.replace.clear()
                if not self.closing and self.lost:
                    self._gather()  # the lost goal's client answered before a new child is awaited
                    self._replace()
                if not self.closing:
                    self.spare.ensure()
                continue
            self._gather()
            process = self.process
            if process is not None and not self.lost and stopped(process.pid):
                self.stop_seen = True
                with contextlib.suppress(OSError):
                    process.kill()  # its pipes close: the loop aborts its goal and asks for a new one

    def _gather(self) -> None:
        """The result requests that arrived (the watching thread): a lost goal's answered."""
        if self.results is None:
            return
        try:
            self.results.gather()
        except Exception:  # noqa: BLE001 - rcl's errors as the node shuts down: the watching thread lives on
            return

    def _replace(self) -> None:
        began = time.monotonic()
        old = self.process
        if old is not None:
            kill(old, 3.0)
        setup = dict(self.setup)
        if self.parameters_now is not None:
            setup["parameters"] = self.parameters_now()
        try:
            process, reader, writer = self._launch(frame(setup), self.spare.take())
        except OSError as exc:
            self.on_restored(f"the goal process could not be started again ({exc}): no action server")
            return
        ok = self._wait_for(reader, "ready", RESTART_WAIT_S, carry_out=False)
        if ok and self.told_serve:
            writer.send(("serve",))
            ok = self._wait_for(reader, "serving", RESTART_WAIT_S, carry_out=False)
        if not ok:
            kill(process, 3.0)
            self.on_restored(f"the new goal process did not serve within {RESTART_WAIT_S:g} s: no action server")
            return
        self._gather()  # requests that arrived for the lost goal while no child served
        if self.results is not None:
            self.results.served()
        with self.swap:
            writer.send(("active", self.active))
            writer.send(("runaway", self.runaway))
            self.process, self.reader, self.writer = process, reader, writer
            self.told_driving = None
            self.lost = False
        self.restarts += 1
        self.on_restored(f"a new goal process (pid {process.pid}) serves the action and the parameters, "
                         f"{time.monotonic() - began:.2f} s after the last one ended")

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
        elif kind == "serving":
            pid = self.process.pid if self.process is not None else None
            self.on_restored(f"the goal process (pid {pid}) serves the action and the parameters")
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
        """End the child (it ends its goals: the controller is stopping) and the watching thread."""
        self.closing = True
        self.replace.set()
        if self.watcher is not None:
            self.watcher.join(timeout=RESTART_WAIT_S + 5.0)
        self.spare.close(3.0)
        process, self.process = self.process, None
        if process is not None:
            end(process, 3.0)  # its input closed: it ends its goals, or is killed


def _feedback_hz() -> float:
    from ..action import FEEDBACK_HZ  # the action module imports rclpy: only where a node runs

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


def parameter_table(node: Any, values: Mapping[str, Any] | None = None) -> list[tuple[bytes, bytes]]:
    """Every parameter ``node`` declared, as its value and its descriptor (both serialized), for
    the child to declare the same (unset ones included: their type is in the descriptor);
    ``values`` replace the node's own (gains a goal process accepted, which the node never set)."""
    from rclpy.parameter import Parameter
    from rclpy.serialization import serialize_message

    from ...rclpy_internals import declared_parameters

    values = values or {}
    return [(serialize_message((Parameter(name, value=values[name]) if name in values else parameter)
                               .to_parameter_msg()), serialize_message(node.describe_parameter(name)))
            for name, parameter in declared_parameters(node).items()]
