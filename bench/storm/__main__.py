"""Benchmark: the controller's loop lateness with and without a storm of client requests (issue 37).

The UR5 in the MuJoCo stand-in (``ros2 run pdsmc_ros mujoco_driver robot:=ur5 rate:=1000.0``) and
the controller in real time (``type:=pd robot:=ur5 mode:=realtime rate:=1000.0``), in a ROS
domain of their own. The loop's timing comes from its ``/pdsmc/controller_timing`` rows
(:meth:`~pdsmc_ros.loop.statistics.LoopStatistics.row`: each commanding tick's wall time and its
lateness after its deadline), taken by a subscription in this process.

Windows of ``--duration`` seconds alternate, ``--rounds`` times: an idle window (the storm's
process connected and quiet), then a storm window, in which separate processes (so that the
storm's own CPU use is what real clients' would be; three, each pacing itself) send, from plain
rclpy clients:

* FollowJointTrajectory goals every ``GOAL_EVERY_S``, MoveIt-style (first point at t = 0 at the
  current position, then a small move around the start position), ended in turn by success,
  by an impossible goal tolerance (GOAL_TOLERANCE_VIOLATED), by a cancel and by the next goal
  (preemption); their feedback flows while they run;
* every ``LARGE_EVERY_S`` a large goal, in turn of ``--large-points`` points (beyond the
  controller's size limit: refused) and of the limit's
  (:data:`~pdsmc_ros.controller.joint_trajectory.MAX_POINTS`: validated);
* ``set_parameters`` calls every ``PARAM_EVERY_S``, valid (the running gains again) and invalid
  (a negative gain, a wrong length, a string) in turn, through a plain service client;
* every ``NODE_EVERY_S`` a new client node in the storm's process (an action client and
  subscriptions to ``/controller/controller_state``, the commands and the joint states, as a
  viewer or a bridge subscribes), destroyed ``NODE_LIFE_S`` later; every
  ``PARTICIPANT_EVERY_S`` the same in a context of its own (a new DDS participant).

Printed: per window the commanding ticks, the lateness p50, p99, p99.9 and worst (us), the missed
deadlines (a tick started more than a period late), the ticks lost (periods without a tick), the
longest period and how long the ticks took (p50, p99.9: a long tick makes the next one late),
how long the controller's and the stand-in's loop threads waited on a run queue (runnable, their
CPU given to something else), the machine's CPU time left idle and spent in the kernel and the
time its host took the virtual CPUs away (steal), the load average at each window's start, and
what the storm did.
Then each missed deadline told by what came before it (a long tick, or a late start after a short
one) and whether the controller's loop waited on the run queue then; at the end, the controller's
line on its effort command's writer thread (how long after each tick its command was written).
``--floor`` runs a bare Python loop beside everything, paced as the controller's loop is, at its
``SCHED_FIFO`` priority, with no ROS and one thread (so no GIL or middleware lock to wait for), and
prints its lateness in each kind of window: what the storm does to any loop on this machine.
``--busy`` keeps one core busy with another process throughout. Target (issue 37): the storm within 1.2x of idle.

``--control`` keeps the storm's processes connected but quiet in the storm windows: the spread
of the ratios between two kinds of window that differ in nothing (the measurement's own noise on
this machine, against which the storm's ratios are read).

Over two rounds or more, each ratio (the rounds pooled) comes with its 95 % interval: p99, p99.9
and worst from a bootstrap that resamples the rounds in pairs (an idle window with the storm
window after it), missed deadlines from the exact interval of a ratio of two Poisson rates. An
interval wholly at or below 1.2 meets the target, one wholly above misses it, one holding 1.2
decides neither (from ``VERDICT_ROUNDS`` rounds; fewer give the intervals only).

The logs directory (named on the ratios' line) keeps each process's log, ``storm.json`` (the
windows, the late ticks and every storm event) and ``timing.npy`` (every commanding tick's
timing row).

Last line: ``idle_p99_us=A storm_p99_us=B ratio_p99=C idle_worst_us=D storm_worst_us=E ratio_worst=F``
(each window kind pooled over the rounds).

Usage: python bench/storm/ [--duration 10] [--rounds 1 (12 for a verdict)] [--busy] [--large-points 10000]
       [--domain N] [--law pd] [--roles goals,params,large,connections] [--control] [--floor]
       (inside the venv, the venv's bin first on PATH)
"""

from __future__ import annotations

import argparse
import contextlib
import ctypes
import json
import os
import random
import select
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parent.parent.parent
sys.path.insert(0, str(ROOT))

from bench.storm.figures import (  # noqa: E402
    CPU_TIMES,
    FLOOR_PRIORITY,
    RUNQUEUE_EVERY_S,
    cpu_times,
    floor_figures,
    kind_mask,
    late_tick_causes,
    machine_figures,
    miss_origins,
    misses_on_run_queue,
    print_table,
    runqueue_ms,
    window_figures,
)
from bench.storm.verdict import (  # noqa: E402
    LEVEL,
    VERDICT_ROUNDS,
    ratio,
    ratio_intervals,
    round_lateness,
    verdict,
)
from pdsmc_ros.controller import joint_trajectory  # noqa: E402
from pdsmc_ros.loop.rt_check import paced_loop  # noqa: E402
from pdsmc_ros.loop.statistics import missed  # noqa: E402

# the controller's size limit for a trajectory (a goal at the limit is validated); 5,000 where it has none
MAX_POINTS = int(getattr(joint_trajectory, "MAX_POINTS", 5_000))

RATE = 1000.0
GOAL_EVERY_S = 0.15
LARGE_EVERY_S = 2.0
PARAM_EVERY_S = 0.1
NODE_EVERY_S = 0.4
NODE_LIFE_S = 0.3
PARTICIPANT_EVERY_S = 2.0
FLOOR_SPIN_S = 50e-6  # --floor: spin before each deadline, as the controller's loop at FIFO does
WORKER_GRACE_S = 60.0  # a storm process answers its window's counts within this long after the window
MOVE_RAD = 0.03  # each goal's move around the start position, per joint
MOVE_S = 0.4
ENDINGS = ("success", "goal_tolerance", "cancel", "preempted")
START_TIMEOUT_S = 300.0  # a loaded machine, numba kernels compiled on a first run


# --------------------------------------------------------------------------- #
# The storm (processes of their own: ``--worker ROLE``)
# --------------------------------------------------------------------------- #
ROLES = ("goals", "params", "large", "connections")
"""The storm's processes: goals, cancels and preemptions; parameter sets; the large goals; the
connections. Each paces itself; apart, none waits for another's slow calls (building a
20,000-point goal, creating a participant take seconds on a loaded machine). ``--roles`` runs
some of them only: which of them delays the loop."""


class Storm:
    """Plain rclpy clients of the controller, driven from one thread (no executor thread)."""

    def __init__(self, role: str, domain: int, large_points: int, seed: int) -> None:
        import rclpy
        import rclpy.executors
        from control_msgs.action import FollowJointTrajectory
        from control_msgs.msg import JointTrajectoryControllerState
        from rcl_interfaces.srv import SetParameters
        from rclpy.action import ActionClient
        from rclpy.qos import DurabilityPolicy, QoSProfile
        from std_msgs.msg import String

        self.rclpy = rclpy
        self.role = role
        self.domain = domain
        self.large_points = large_points
        self.random = random.Random(seed)
        self.context = rclpy.Context()
        rclpy.init(context=self.context, domain_id=domain)
        self.node = rclpy.create_node(f"storm_{role}", context=self.context)
        self.executor = rclpy.executors.SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.action = ActionClient(self.node, FollowJointTrajectory, "/controller/follow_joint_trajectory")
        self.set_client = self.node.create_client(SetParameters, "/controller/set_parameters")
        self.state: Any = None
        self.description: dict[str, Any] | None = None
        self.node.create_subscription(JointTrajectoryControllerState, "/controller/controller_state",
                                      self._on_state, 10)
        self.node.create_subscription(String, "/pdsmc/run_description", self._on_description,
                                      QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL))
        self.counts: dict[str, int] = {}
        self.events: list[tuple[float, str]] = []  # (wall time, what) of each count in this window
        self.home: np.ndarray | None = None
        self.names: list[str] = []
        self.large: list[Any] = []  # the large goals, built once (20,000 points take seconds in Python)
        self.active: list[Any] = []  # goal handles not yet ended: (handle, ending, when to act)
        self.guests: list[tuple[float, Any, Any]] = []  # (when to destroy, node, context or None)
        self.guest_number = 0

    def _on_state(self, msg: Any) -> None:
        self.state = msg

    def _on_description(self, msg: Any) -> None:
        self.description = json.loads(msg.data)

    def count(self, what: str, n: int = 1) -> None:
        self.counts[what] = self.counts.get(what, 0) + n
        self.events.append((time.time(), what))

    def spin_until(self, condition: Any, seconds: float) -> bool:
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            if condition():
                return True
            self.executor.spin_once(timeout_sec=0.01)
        return bool(condition())

    def ready(self) -> bool:
        """The action server found, a controller state and the run description received."""
        if not self.action.wait_for_server(timeout_sec=START_TIMEOUT_S):
            return False
        if not self.spin_until(lambda: self.state is not None and self.description is not None, 30.0):
            return False
        self.names = list(self.state.joint_names)
        self.home = np.asarray(self.state.feedback.positions, dtype=float)
        if self.role == "large":  # in turn: beyond the controller's size limit, and at it
            self.large = [self._goal(self.large_points), self._goal(MAX_POINTS)]
        return self.set_client.wait_for_service(timeout_sec=30.0)

    # -- goals ---------------------------------------------------------------- #
    def _goal(self, points: int = 2, tolerance: float = 0.0) -> Any:
        """A move from the current position to a point near the start position, MoveIt-style."""
        from builtin_interfaces.msg import Duration
        from control_msgs.action import FollowJointTrajectory
        from control_msgs.msg import JointTolerance
        from trajectory_msgs.msg import JointTrajectoryPoint

        assert self.home is not None  # noqa: S101 - a benchmark's own state (ready() sets it)
        start = np.asarray(self.state.feedback.positions, dtype=float)
        target = self.home + np.array([self.random.uniform(-MOVE_RAD, MOVE_RAD) for _ in self.names])
        goal = FollowJointTrajectory.Goal()
        goal.trajectory.joint_names = self.names
        zero = [0.0] * len(self.names)
        for k in range(points):
            s = k / (points - 1)
            t = s * MOVE_S * max(1.0, points / 1000.0)
            goal.trajectory.points.append(JointTrajectoryPoint(
                positions=(start + s * (target - start)).tolist(), velocities=zero if points == 2 else [],
                time_from_start=Duration(sec=int(t), nanosec=int((t % 1.0) * 1e9))))
        if tolerance:
            goal.goal_tolerance = [JointTolerance(name=n, position=tolerance) for n in self.names]
            goal.goal_time_tolerance = Duration(nanosec=50_000_000)
        return goal

    def send_goal(self, ending: str, goal: Any = None) -> None:
        large = goal is not None
        if goal is None:
            goal = self._goal(2, 1e-7 if ending == "goal_tolerance" else 0.0)
        self.count("large goals sent" if large else "goals sent")
        future = self.action.send_goal_async(goal)
        future.add_done_callback(lambda f: self._on_response(f, ending))

    def _on_response(self, future: Any, ending: str) -> None:
        handle = future.result()
        if handle is None or not handle.accepted:
            self.count("goals rejected")
            return
        self.count("goals accepted")
        act_at = time.monotonic() + (0.1 if ending == "cancel" else 0.0)
        self.active.append((handle, ending, act_at))
        handle.get_result_async().add_done_callback(lambda f: self._on_result(f, handle))

    def _on_result(self, future: Any, handle: Any) -> None:
        result = future.result()
        status = {4: "succeeded", 5: "canceled", 6: "aborted"}.get(getattr(result, "status", 0), "other")
        self.count(f"goals {status}")
        self.active = [a for a in self.active if a[0] is not handle]

    def act_on_goals(self, now: float) -> None:
        for handle, ending, at in list(self.active):
            if ending == "cancel" and now >= at:
                handle.cancel_goal_async()
                self.count("cancels")
                self.active = [a for a in self.active if a[0] is not handle]

    # -- parameters ----------------------------------------------------------- #
    def set_parameters(self, k: int) -> None:
        """``kp`` set to the running gains (valid) or to a negative gain, a wrong length, a string."""
        from rcl_interfaces.msg import Parameter, ParameterType, ParameterValue
        from rcl_interfaces.srv import SetParameters

        n = len(self.names)
        kp = list((self.description or {}).get("gains", {}).get("kp", [])) or [100.0] * n
        values = [
            ParameterValue(type=ParameterType.PARAMETER_DOUBLE_ARRAY, double_array_value=kp),
            ParameterValue(type=ParameterType.PARAMETER_DOUBLE_ARRAY, double_array_value=[-1.0] * n),
            ParameterValue(type=ParameterType.PARAMETER_DOUBLE_ARRAY, double_array_value=kp[: n - 1]),
            ParameterValue(type=ParameterType.PARAMETER_STRING, string_value="x" * n),
        ]
        request = SetParameters.Request(parameters=[Parameter(name="kp", value=values[k % len(values)])])
        self.count("parameter sets")
        future = self.set_client.call_async(request)
        future.add_done_callback(self._on_set)

    def _on_set(self, future: Any) -> None:
        response = future.result()
        ok = response is not None and response.results and response.results[0].successful
        self.count("parameter sets accepted" if ok else "parameter sets refused")

    # -- connections ---------------------------------------------------------- #
    def connect(self, own_context: bool) -> None:
        """A new client node (its own context: a new DDS participant) with an action client and
        subscriptions to the controller state and, as a viewer or a bridge would, to the commands
        and the joint states, destroyed NODE_LIFE_S later."""
        from control_msgs.action import FollowJointTrajectory
        from control_msgs.msg import JointTrajectoryControllerState
        from rclpy.action import ActionClient
        from sensor_msgs.msg import JointState
        from std_msgs.msg import Float64MultiArray

        context = None
        if own_context:
            context = self.rclpy.Context()
            self.rclpy.init(context=context, domain_id=self.domain)
        self.guest_number += 1
        node = self.rclpy.create_node(f"storm_guest_{os.getpid()}_{self.guest_number}",
                                      context=context or self.context)
        ActionClient(node, FollowJointTrajectory, "/controller/follow_joint_trajectory")
        node.create_subscription(JointTrajectoryControllerState, "/controller/controller_state", lambda m: None, 10)
        node.create_subscription(Float64MultiArray, "/effort_controller/commands", lambda m: None, 10)
        node.create_subscription(JointState, "/joint_states", lambda m: None, 10)
        self.count("connections")
        if own_context:
            self.count("new participants")
        self.guests.append((time.monotonic() + NODE_LIFE_S, node, context))

    def disconnect(self, now: float, everyone: bool = False) -> None:
        keep = []
        for until, node, context in self.guests:
            if everyone or now >= until:
                node.destroy_node()
                self.count("disconnections")
                if context is not None:
                    self.rclpy.try_shutdown(context=context)
            else:
                keep.append((until, node, context))
        self.guests = keep

    # -- the storm ------------------------------------------------------------ #
    def run(self, seconds: float) -> dict[str, Any]:
        """This role's part of the storm for ``seconds``; what it did (counts, and ``events``: each
        one's wall time)."""
        self.counts = {}
        self.events = []
        start = time.monotonic()
        end = start + seconds
        every = {"goals": (("goal", GOAL_EVERY_S),), "params": (("param", PARAM_EVERY_S),),
                 "large": (("large", LARGE_EVERY_S),),
                 "connections": (("node", NODE_EVERY_S), ("participant", PARTICIPANT_EVERY_S))}[self.role]
        due = {what: start for what, _ in every}
        done = dict.fromkeys(due, 0)
        while (now := time.monotonic()) < end:
            for what, interval in every:
                if now < due[what]:
                    continue
                k = done[what]
                if what == "goal":
                    self.send_goal(ENDINGS[k % len(ENDINGS)])  # "preempted": the next goal preempts it
                elif what == "param":
                    self.set_parameters(k)
                elif what == "large":
                    self.send_goal("success", self.large[k % len(self.large)])
                else:
                    self.connect(own_context=what == "participant")
                done[what] += 1
                due[what] = max(due[what] + interval, time.monotonic())
            self.act_on_goals(now)
            self.disconnect(now)
            self.executor.spin_once(timeout_sec=0.002)
        self.disconnect(0.0, everyone=True)
        # the last goals' answers (and a hold after them), so the next idle window starts quiet
        for handle, _, _ in list(self.active):
            handle.cancel_goal_async()
        self.spin_until(lambda: not self.active, 3.0)
        return {**self.counts, "events": self.events}

    def rest(self, seconds: float) -> dict[str, Any]:
        """A control window (``--control``): connected, subscribed and spinning as in the idle
        windows, for ``seconds``, sending nothing."""
        self.spin_until(lambda: False, seconds)
        return {"events": []}

    def close(self) -> None:
        self.disconnect(0.0, everyone=True)
        self.action.destroy()
        self.node.destroy_node()
        self.rclpy.try_shutdown(context=self.context)


def worker(role: str, domain: int, large_points: int, seed: int) -> int:
    """A storm process: "ready" once connected, then one storm per "go SECONDS" line on stdin (a
    quiet window per "rest SECONDS")."""
    storm = Storm(role, domain, large_points, seed)
    try:
        if not storm.ready():
            print(json.dumps({"error": f"{role}: the controller's action server, state or parameters did not "
                                       "answer"}), flush=True)
            return 1
        print(json.dumps({"ready": True}), flush=True)
        for line in sys.stdin:
            words = line.split()
            if not words or words[0] not in ("go", "rest"):
                break
            seconds = float(words[1])
            print(json.dumps(storm.run(seconds) if words[0] == "go" else storm.rest(seconds)), flush=True)
        return 0
    finally:
        storm.close()


def floor_loop(out: Path, seconds: float) -> int:
    """``--floor``'s process: ``pdsmc rt-check``'s bare loop (:func:`~pdsmc_ros.loop.rt_check.paced_loop`:
    paced as the serve loop paces the nodes, ``FLOOR_SPIN_S`` of spin before each deadline at
    ``RATE``) at the controller loop's ``SCHED_FIFO`` priority with memory locked, one thread, no
    ROS: what the machine alone does to a loop beside the storm. Runs until its stdin closes (at
    most ``seconds``); saves each tick's (wall time, lateness after its deadline) to ``out``."""
    with contextlib.suppress(OSError, AttributeError):
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(FLOOR_PRIORITY))
    with contextlib.suppress(OSError, AttributeError):
        ctypes.CDLL(None, use_errno=True).mlockall(3)  # MCL_CURRENT | MCL_FUTURE: the loop's arrays too
    ended = threading.Event()
    threading.Thread(target=lambda: (sys.stdin.read(), ended.set()), daemon=True).start()
    wall_offset = time.time() - time.perf_counter()
    late, starts, _ = paced_loop(1.0 / RATE, seconds, FLOOR_SPIN_S, stop=ended)
    np.save(out, np.column_stack([starts + wall_offset, late]))
    return 0


# --------------------------------------------------------------------------- #
# The measurement (this process)
# --------------------------------------------------------------------------- #
class TimingRows:
    """``/pdsmc/controller_timing`` rows taken by a subscription spun in a thread of its own."""

    def __init__(self, domain: int) -> None:
        import rclpy
        import rclpy.executors
        from std_msgs.msg import Float64MultiArray

        from pdsmc_ros.loop.statistics import LoopStatistics
        from pdsmc_ros.ros.topics import STREAM_QOS, TOPIC_TIMING

        self.width = LoopStatistics.ROW_FIELDS
        self.rclpy = rclpy
        self.context = rclpy.Context()
        rclpy.init(context=self.context, domain_id=domain)
        self.node = rclpy.create_node("storm_timing", context=self.context)
        self.lock = threading.Lock()
        self.rows: list[np.ndarray] = []
        self.node.create_subscription(Float64MultiArray, f"/{TOPIC_TIMING}", self._on_rows, STREAM_QOS)
        self.executor = rclpy.executors.SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self._spin, daemon=True)
        self.thread.start()

    def _on_rows(self, msg: Any) -> None:
        with self.lock:
            self.rows.append(np.asarray(msg.data, dtype=float).reshape(-1, self.width))

    def _spin(self) -> None:
        while not self.stop.is_set():
            self.executor.spin_once(timeout_sec=0.05)

    def all(self) -> np.ndarray:
        with self.lock:
            return np.concatenate(self.rows) if self.rows else np.zeros((0, self.width))

    def close(self) -> None:
        self.stop.set()
        self.thread.join(timeout=2)
        self.node.destroy_node()
        self.rclpy.try_shutdown(context=self.context)


class RunQueueWaits:
    """How long the processes' main threads (the controller's and the stand-in's loops) waited on
    a run queue: runnable, but the CPU given to something else (``/proc/PID/schedstat``'s second
    field, sampled every ``RUNQUEUE_EVERY_S``). A thread at ``SCHED_FIFO`` waits there only for a
    thread of higher or equal priority, or for a kernel that does not preempt (``Dynamic Preempt:
    none`` in the boot log: a task in a long system call keeps its CPU until it returns), never for
    the GIL or a lock (a thread waiting for those sleeps)."""

    def __init__(self, pids: dict[str, int]) -> None:
        self.pids = pids
        self.samples: list[tuple[float, ...]] = []  # (wall time, waited ns per pid)
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self._sample, daemon=True)
        self.thread.start()

    @staticmethod
    def waited(pid: int) -> float:
        try:
            return float(Path(f"/proc/{pid}/schedstat").read_text().split()[1])
        except (OSError, IndexError, ValueError):
            return float("nan")

    def _sample(self) -> None:
        while not self.stop.wait(RUNQUEUE_EVERY_S):
            self.samples.append((time.time(), *(self.waited(pid) for pid in self.pids.values())))

    def array(self) -> np.ndarray:
        return np.array(self.samples) if self.samples else np.zeros((0, 1 + len(self.pids)))

    def close(self) -> None:
        self.stop.set()
        self.thread.join(timeout=2)


def answer(proc: subprocess.Popen[Any]) -> dict[str, Any]:
    """A storm process's next answer: its next line that is a JSON object. Fast DDS logs its own
    errors to the standard output, which is the answers' pipe; such lines go to stderr."""
    for line in proc.stdout:  # type: ignore[union-attr]
        if line.startswith("{"):
            return json.loads(line)
        print(f"storm process: {line.rstrip()}", file=sys.stderr)
    return {}


def stop(proc: subprocess.Popen[Any] | None, signal_first: int = 2) -> None:
    if proc is None or proc.poll() is not None:
        return
    proc.send_signal(signal_first)
    try:
        proc.wait(timeout=20)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait(timeout=10)


def load() -> str:
    return " ".join(f"{v:.2f}" for v in os.getloadavg())


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=10.0, help="seconds of each window (default 10)")
    parser.add_argument("--rounds", type=int, default=1, help="idle and storm windows, alternating (default 1)")
    parser.add_argument("--busy", action="store_true", help="another process keeps one core busy throughout")
    parser.add_argument("--large-points", type=int, default=10_000,
                        help="points of the storm's large goal, one every 2 s (default 10000)")
    parser.add_argument("--law", default="pd", help="the controller's law (default pd)")
    parser.add_argument("--domain", type=int, default=os.getpid() % 150 + 60)
    parser.add_argument("--param", action="append", default=[],
                        help="an extra controller parameter, e.g. --param thread_priority:=0")
    parser.add_argument("--roles", default=",".join(ROLES),
                        help=f"the storm's processes, comma-separated, of {', '.join(ROLES)} (default all)")
    parser.add_argument("--control", action="store_true",
                        help="a control run: the storm's processes stay connected but quiet in the storm windows "
                             "(the ratios' noise on this machine)")
    parser.add_argument("--floor", action="store_true",
                        help="a bare Python loop at the controller loop's SCHED_FIFO priority beside the run: the "
                             "machine's own share of the lateness in each kind of window")
    parser.add_argument("--floor-out", type=Path, help=argparse.SUPPRESS)
    parser.add_argument("--worker", choices=ROLES, help=argparse.SUPPRESS)
    parser.add_argument("--seed", type=int, default=37, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if not 1.0 <= args.duration <= 600.0:
        parser.error(f"--duration must be in [1, 600] s, got {args.duration:g}")
    if not 1 <= args.rounds <= 20:
        parser.error(f"--rounds must be in [1, 20], got {args.rounds}")
    if not 2 <= args.large_points <= 1_000_000:
        parser.error(f"--large-points must be in [2, 1000000], got {args.large_points}")
    roles = [r.strip() for r in args.roles.split(",") if r.strip()]
    if not roles or any(r not in ROLES for r in roles):
        parser.error(f"--roles must name some of {', '.join(ROLES)}, got {args.roles!r}")
    if args.worker:
        return worker(args.worker, args.domain, args.large_points, args.seed)
    if args.floor_out:
        return floor_loop(args.floor_out, args.rounds * 2 * (args.duration + WORKER_GRACE_S) + 60.0)

    env = dict(os.environ, ROS_DOMAIN_ID=str(args.domain), ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST")
    logs = Path(tempfile.mkdtemp(prefix="storm-"))
    procs: list[subprocess.Popen[Any]] = []
    busy = None
    storms: list[subprocess.Popen[Any]] = []
    timing = None
    runqueue = None
    floor = None
    try:
        with open(logs / "driver.log", "w") as out:
            procs.append(subprocess.Popen(
                ["ros2", "run", "pdsmc_ros", "mujoco_driver", "--ros-args", "-p", "robot:=ur5", "-p", f"rate:={RATE}"],
                env=env, stdout=out, stderr=subprocess.STDOUT, start_new_session=True))
        with open(logs / "controller.log", "w") as out:
            procs.append(subprocess.Popen(
                ["ros2", "run", "pdsmc_ros", "controller", "--ros-args", "-p", f"type:={args.law}", "-p", "robot:=ur5",
                 "-p", "mode:=realtime", "-p", f"rate:={RATE}", *(a for p in args.param for a in ("-p", p))],
                env=env, stdout=out, stderr=subprocess.STDOUT, start_new_session=True))
        timing = TimingRows(args.domain)
        deadline = time.monotonic() + START_TIMEOUT_S
        while len(timing.all()) < 1000 and time.monotonic() < deadline:
            if any(p.poll() is not None for p in procs):
                break
            time.sleep(0.2)
        if len(timing.all()) < 1000:
            print(f"bench/storm/: error: the controller did not command (logs in {logs})", file=sys.stderr)
            return 1
        if args.floor:
            floor = subprocess.Popen([sys.executable, __file__, "--floor-out", str(logs / "floor.npy"),
                                      "--rounds", str(args.rounds), "--duration", str(args.duration)],
                                     stdin=subprocess.PIPE, start_new_session=True)
        sampled = {"controller": procs[1].pid, "driver": procs[0].pid}  # ros2 run execs: the same pid
        if floor is not None:
            sampled["floor"] = floor.pid
        runqueue = RunQueueWaits(sampled)
        for role in roles:  # one after the other: participants created at the same instant hung here
            storms.append(subprocess.Popen(
                [sys.executable, __file__, "--worker", role, "--domain", str(args.domain),
                 "--large-points", str(args.large_points), "--seed", str(args.seed)],
                env=env, stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, start_new_session=True))
            hello = answer(storms[-1])
            if not hello.get("ready"):
                print(f"bench/storm/: error: the storm's {role} clients did not connect: {hello}", file=sys.stderr)
                return 1
        if args.busy:
            busy = subprocess.Popen([sys.executable, "-c", "while True: pass"])
        time.sleep(2.0)  # the storm's connection settles
        windows: list[tuple[str, float, float, str]] = []
        did: dict[str, int] = {}
        events: list[tuple[float, str]] = []  # (wall time, what) of everything the storm did
        spent: list[np.ndarray] = []  # each window's CPU time by kind (cpu_times)
        for _ in range(args.rounds):
            start, loaded, before = time.time(), load(), cpu_times()
            time.sleep(args.duration)
            windows.append(("idle", start, time.time(), loaded))
            spent.append(cpu_times() - before)
            start, loaded, before = time.time(), load(), cpu_times()
            for proc in storms:
                proc.stdin.write(f"{'rest' if args.control else 'go'} {args.duration}\n")  # type: ignore[union-attr]
                proc.stdin.flush()  # type: ignore[union-attr]
            for role, proc in zip(roles, storms, strict=True):
                # a client that hangs (rclpy once stood still destroying a guest node) fails the run, never hangs it
                if not select.select([proc.stdout], [], [], args.duration + WORKER_GRACE_S)[0]:
                    print(f"bench/storm/: error: the storm's {role} clients did not answer within "
                          f"{args.duration + WORKER_GRACE_S:g} s of their window (logs in {logs})", file=sys.stderr)
                    return 1
                counts = answer(proc)
                events.extend((float(t), str(what)) for t, what in counts.pop("events", []))
                for key, value in counts.items():
                    did[key] = did.get(key, 0) + value
            windows.append(("storm", start, start + args.duration, loaded))
            spent.append(cpu_times() - before)  # to the last answer, a moment past the window
            time.sleep(1.0)  # the storm's tail (last answers, a hold) outside both windows
        time.sleep(0.5)  # the last timing batch
        rows = timing.all()
        if floor is not None:
            floor.stdin.close()  # type: ignore[union-attr]
            with contextlib.suppress(subprocess.TimeoutExpired):
                floor.wait(timeout=30)  # it saves its ticks; else killed below, and its figures are missing
        period = 1.0 / RATE
        label = {"idle": "idle", "storm": "control" if args.control else "storm"}  # the second window of each round
        samples = runqueue.array()
        labelled = [(f"{label[kind]} {k // 2 + 1}",
                     window_figures(rows, a, b, period) | runqueue_ms(samples, list(sampled), a, b)
                     | machine_figures(spent[k]), loaded)
                    for k, (kind, a, b, loaded) in enumerate(windows)]
        pooled = {}
        for kind in ("idle", "storm"):
            pooled[kind] = window_figures(rows[kind_mask(rows[:, 0], windows, kind)], -np.inf, np.inf, period)
            for key in (f"{name}_rq_ms" for name in sampled):
                pooled[kind][key] = sum(f.get(key, 0.0) for (name, *_), (_, f, _) in zip(windows, labelled, strict=True)
                                        if name == kind)
            pooled[kind] |= machine_figures(sum((d for (name, *_), d in zip(windows, spent, strict=True)
                                                 if name == kind), np.zeros(len(CPU_TIMES))))
        print(f"controller {args.law}, UR5 against the MuJoCo stand-in, {RATE:g} Hz real time, windows of "
              f"{args.duration:g} s{', one core kept busy' if args.busy else ''}; lateness of each commanding tick "
              "after its deadline")
        if args.control:
            print("a control run: in the control windows the storm's processes are connected and quiet")
        print_table(labelled + [(f"{label[kind]} (all)", pooled[kind], "") for kind in ("idle", "storm")])
        print("storm: " + ", ".join(f"{key} {value}" for key, value in sorted(did.items())))
        late = rows[missed(rows[:, 3], period)]
        print(late_tick_causes(late, windows, events))
        print(miss_origins(rows, windows, period))
        print(misses_on_run_queue(late, samples, windows, period))
        if (logs / "floor.npy").exists():
            print(floor_figures(np.load(logs / "floor.npy"), windows, period)
                  + f"; its run-queue waits {pooled['idle'].get('floor_rq_ms', 0.0):.1f} ms idle, "
                  f"{pooled['storm'].get('floor_rq_ms', 0.0):.1f} ms in the storm")
        (logs / "storm.json").write_text(json.dumps({  # for a closer look: the late ticks and every storm event
            "windows": windows, "late_ticks": late[:, :4].tolist(), "events": events,
            "runqueue_waits_ns": samples.tolist()}))
        np.save(logs / "timing.npy", rows)  # every commanding tick's row (LoopStatistics.row)
        empty = [name for name, figures, _ in labelled if figures["ticks"] < 2]
        if empty:  # the timing rows stopped reaching this process: no figure of those windows is known
            last = f"{rows[-1, 0]:.3f}" if len(rows) else "none"
            print(f"bench/storm/: error: no timing rows in windows {', '.join(empty)} (the last row's wall time "
                  f"{last}; logs in {logs}): the run is not measured", file=sys.stderr)
            return 1
        idle, busy_figures = pooled["idle"], pooled["storm"]
        print(f"ratios {label['storm']}/idle: p99 {ratio(busy_figures['p99_us'], idle['p99_us']):.2f}, p99.9 "
              f"{ratio(busy_figures['p999_us'], idle['p999_us']):.2f}, worst "
              f"{ratio(busy_figures['worst_us'], idle['worst_us']):.2f}, missed "
              f"{busy_figures['missed']:.0f} vs {idle['missed']:.0f} (logs: {logs})")
        kinds = round_lateness(rows, windows)
        if len(kinds["idle"]) >= 2:
            intervals = ratio_intervals(kinds["idle"], kinds["storm"], period)
            print(f"{label['storm']}/idle over {len(kinds['idle'])} rounds, {100 * LEVEL:g} % intervals (rounds "
                  f"resampled in pairs; missed deadlines: exact Poisson rate ratio):")
            for name, (point, low, high) in intervals.items():
                told = verdict(low, high) if len(kinds["idle"]) >= VERDICT_ROUNDS else \
                    f"(a verdict needs {VERDICT_ROUNDS} rounds or more)"
                print(f"  {name:6s} {point:6.2f}  [{low:.2f}, {high:.2f}]  {told}")
        print(f"idle_p99_us={idle['p99_us']:.0f} storm_p99_us={busy_figures['p99_us']:.0f} "
              f"ratio_p99={ratio(busy_figures['p99_us'], idle['p99_us']):.2f} "
              f"idle_worst_us={idle['worst_us']:.0f} storm_worst_us={busy_figures['worst_us']:.0f} "
              f"ratio_worst={ratio(busy_figures['worst_us'], idle['worst_us']):.2f}")
        return 0
    finally:
        for proc in storms:
            with contextlib.suppress(OSError):
                proc.stdin.close()  # type: ignore[union-attr]
        for proc in storms:
            try:
                proc.wait(timeout=15)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait(timeout=10)
        if floor is not None and floor.poll() is None:
            floor.kill()
            floor.wait(timeout=10)
        if busy is not None:
            busy.kill()
            busy.wait(timeout=10)
        if timing is not None:
            timing.close()
        if runqueue is not None:
            runqueue.close()
        for proc in reversed(procs):
            stop(proc)
        # the controller's closing line on its effort command's writer thread: how late the commands left
        with contextlib.suppress(OSError):
            for line in (logs / "controller.log").read_text(errors="replace").splitlines():
                if "written by its own thread" in line:
                    print("command writes: " + line.split("]: ", 1)[-1])


if __name__ == "__main__":
    sys.exit(main())
