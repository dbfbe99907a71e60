"""Benchmark: how fast the UR5 moves around the ends of FollowJointTrajectory goals (issue 37).

The UR5 in the MuJoCo stand-in (``ros2 run pdsmc_ros mujoco_driver robot:=ur5``, 1 kHz) and the
controller in real time (``mode:=realtime rate:=1000.0``, the shipped gains of each law), driven
by a plain rclpy action client in this process. For every law, ``--goals`` goals of each ending:

* ``success``: a 0.3 rad move of every joint over 1.5 s, MoveIt-style (first point at t = 0 at
  the current position, empty tolerances);
* ``goal_tolerance``: the same move with an impossible goal tolerance (1e-6 rad, 0.1 s of goal
  time): GOAL_TOLERANCE_VIOLATED;
* ``path_tolerance``: the same move with a 1e-4 rad path tolerance: PATH_TOLERANCE_VIOLATED;
* ``cancel``: canceled 0.75 s into the move;
* ``preemption``: a second goal sent 0.75 s into the first, back to the start in 1.5 s (one point,
  at t = 1.5 s: the controller interpolates from where the arm is, so it is not refused as a step
  for a state the client received late); the first ends preempted (INVALID_GOAL), the window
  after its end covers the second goal;
* ``step``: a first point at t = 0, 0.3 rad away from the current position (refused, or a step).

Measured from the stand-in's ``/joint_states`` (its true rates) as the project's recorder
(``ros2 run pdsmc_ros recorder``, graph mode, keep-all) writes them into a bag beside the run,
timed by their stamps (the driver's wall clock): the largest ``|qd_i| / v_max_i`` over the 2 s
after each end (target: below 0.25) and over the whole run (target: below 1), the joint it was on,
and how each goal ended. (A Python client spinning at 1 kHz falls seconds behind on a loaded
machine and drops states; the recorder takes them in batches.) ``--busy`` keeps one core busy with
another process throughout. Each law's line ``states`` gives the states in the bag over the run's
span against 1 kHz (fewer: some were lost, a peak may be missed).

Last line: ``worst_after_end_ratio=A worst_ratio=B`` (the worst over every law and ending).

Usage: python bench/goal_ends.py [--laws pd,smc,pdsmc] [--goals 10] [--busy]   (inside the venv,
after make setup; the venv's bin first on PATH)
"""

from __future__ import annotations

import argparse
import contextlib
import os
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from builtin_interfaces.msg import Duration  # noqa: E402
from control_msgs.action import FollowJointTrajectory  # noqa: E402
from control_msgs.msg import JointTolerance  # noqa: E402
from rclpy.action import ActionClient  # noqa: E402
from sensor_msgs.msg import JointState  # noqa: E402
from trajectory_msgs.msg import JointTrajectoryPoint  # noqa: E402

from pdsmc_ros.robots.catalog import resolve_robot  # noqa: E402
from pdsmc_ros.robots.registry import make_robot  # noqa: E402
from pdsmc_ros.ros.spun_node import SpunNode  # noqa: E402

ENDINGS = ("success", "goal_tolerance", "path_tolerance", "cancel", "preemption", "step")
MOVE = 0.3  # rad, every joint
MOVE_S = 1.5
AFTER_S = 2.0
CODES = {0: "SUCCESSFUL", -1: "INVALID_GOAL", -2: "INVALID_JOINTS", -3: "OLD_HEADER_TIMESTAMP",
         -4: "PATH_TOLERANCE_VIOLATED", -5: "GOAL_TOLERANCE_VIOLATED"}


def duration(seconds: float) -> Duration:
    return Duration(sec=int(seconds), nanosec=int(round((seconds % 1.0) * 1e9)))


class Client(SpunNode):
    """An rclpy node spun by a thread of its own: the stand-in's states and an action client."""

    def __init__(self, domain: int, names: list[str]) -> None:
        super().__init__(domain, "goal_ends_bench")
        self.names = names
        self.lock = threading.Lock()
        self.foreign = 0  # /joint_states without this arm's joints (another run on the domain)
        self.states: list[tuple[float, np.ndarray, np.ndarray]] = []  # (stamp, q, qd) in ``names`` order
        self.node.create_subscription(JointState, "/joint_states", self.on_state, 10)  # the latest
        self.action = ActionClient(self.node, FollowJointTrajectory, "/controller/follow_joint_trajectory")

    def on_state(self, msg: JointState) -> None:
        if not set(self.names) <= set(msg.name):  # another arm's, on the same domain
            self.foreign += 1
            return
        index = [list(msg.name).index(n) for n in self.names]
        stamp = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9
        with self.lock:
            self.states.append((stamp, np.asarray(msg.position)[index], np.asarray(msg.velocity)[index]))

    def q(self) -> np.ndarray:
        with self.lock:
            return self.states[-1][1].copy()

    def between(self, start: float, end: float, position: bool = False) -> np.ndarray:
        """The velocities (or positions) stamped in ``[start, end]`` (wall clock, s)."""
        with self.lock:
            rows = [q if position else qd for t, q, qd in self.states if start <= t <= end]
        return np.array(rows) if rows else np.zeros((0, len(self.names)))

    def call(self, make: Callable[[], Any], seconds: float = 30.0, why: Callable[[], str] = str) -> Any:  # noqa: ANN401
        """The answer, or None if none came within ``seconds`` (the bench reports it)."""
        try:
            return super().call(make, seconds, why)
        except TimeoutError:
            return None



def goal(names: list[str], start: np.ndarray | None, target: np.ndarray, *, step: bool = False,
         path: float = 0.0, goal_tolerance: float = 0.0, seconds: float = MOVE_S) -> FollowJointTrajectory.Goal:
    """From ``start`` at t = 0 (None: no point at t = 0, the controller starts from where the arm is)
    to ``target`` at ``seconds``; ``step``: the first point at t = 0 is ``target``."""
    g = FollowJointTrajectory.Goal()
    g.trajectory.joint_names = names
    zero = [0.0] * len(names)
    points = [JointTrajectoryPoint(positions=target.tolist(), velocities=zero, time_from_start=duration(seconds))]
    if step or start is not None:
        first = target if step or start is None else start
        points.insert(0, JointTrajectoryPoint(positions=first.tolist(), velocities=zero,
                                              time_from_start=duration(0.0)))
    g.trajectory.points = points
    if path:
        g.path_tolerance = [JointTolerance(name=n, position=path) for n in names]
    if goal_tolerance:
        g.goal_tolerance = [JointTolerance(name=n, position=goal_tolerance) for n in names]
        g.goal_time_tolerance = duration(0.1)
    return g


def run_goal(client: Client, names: list[str], ending: str, sign: float) -> tuple[str, float]:
    """One goal ended as ``ending``: ``(how it ended, the time it ended (wall clock))``."""
    start = client.q()
    target = start + sign * MOVE
    g = goal(names, start, target, step=ending == "step", path=1e-4 if ending == "path_tolerance" else 0.0,
             goal_tolerance=1e-6 if ending == "goal_tolerance" else 0.0)
    handle = client.call(lambda: client.action.send_goal_async(g))
    if handle is None:
        return "no answer", time.time()
    if not handle.accepted:
        return "rejected", time.time()
    if ending == "cancel":
        time.sleep(0.75)
        ended = time.time()
        client.call(lambda: handle.cancel_goal_async())
        return _outcome(client.call(lambda: handle.get_result_async(), 10.0)), ended
    if ending == "preemption":
        time.sleep(0.75)
        second = goal(names, None, start)
        ended = time.time()
        other = client.call(lambda: client.action.send_goal_async(second))
        result = client.call(lambda: handle.get_result_async(), 10.0)
        if other is not None and other.accepted:
            client.call(lambda: other.get_result_async(), 10.0)  # back where it started
        return _outcome(result), ended
    result = client.call(lambda: handle.get_result_async(), 30.0)
    return _outcome(result), time.time()


def _outcome(result: Any) -> str:  # noqa: ANN401
    if result is None:
        return "no result"
    code = result.result.error_code
    return CODES.get(code, str(code)) if code else ("SUCCESSFUL" if result.status == 4 else "CANCELED")


Row = tuple[float, str, list[str]]
"""One ending's figures: the largest ``|qd|/v_max``, the joint it was on, how the goals ended."""


def recorded_states(bag: Path, names: list[str]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(stamps (s, wall clock), positions, velocities)`` of the ``/joint_states`` in ``bag``, ``names`` order."""
    from rosbags.rosbag2 import Reader

    from pdsmc_ros.bag.cdr import decode_joint_state_named

    stamps, q, qd = [], [], []
    with Reader(bag) as reader:
        connections = [c for c in reader.connections if c.topic == "/joint_states"]
        for _, _, raw in reader.messages(connections=connections):
            order, sec, nanosec, position, velocity, _ = decode_joint_state_named(raw)
            if not set(names) <= set(order):  # another arm's, on the same domain
                continue
            index = [list(order).index(n) for n in names]
            stamps.append(sec + nanosec * 1e-9)
            q.append(np.asarray(position)[index])
            qd.append(np.asarray(velocity)[index])
    if not stamps:
        return np.zeros(0), np.zeros((0, len(names))), np.zeros((0, len(names)))
    return np.array(stamps), np.array(q), np.array(qd)


@contextlib.contextmanager
def running(law: str, names: list[str], domain: int, env: dict[str, str], logs: Path,
            tag: str = "", bag: Path | None = None) -> Iterator[Client]:
    """The stand-in (UR5, 1 kHz) and the controller (``law``, real time, shipped gains) running, the
    client connected, the arm settled on its activation's hold; ``bag``: the recorder writes
    ``/joint_states`` there from before the controller starts. All stopped (SIGINT) afterwards."""
    procs = []
    try:
        if bag is not None:
            with open(logs / f"{law}{tag}-recorder.log", "w") as out:
                procs.append(subprocess.Popen(
                    ["ros2", "run", "pdsmc_ros", "recorder", "--ros-args", "-p", f"output:={bag}",
                     "-p", "topics:=[/joint_states]"], env=env, stdout=out, stderr=subprocess.STDOUT))
        with open(logs / f"{law}{tag}-driver.log", "w") as out:
            procs.append(subprocess.Popen(
                ["ros2", "run", "pdsmc_ros", "mujoco_driver", "--ros-args", "-p", "robot:=ur5", "-p", "rate:=1000.0"],
                env=env, stdout=out, stderr=subprocess.STDOUT))
        with open(logs / f"{law}{tag}-controller.log", "w") as out:
            procs.append(subprocess.Popen(
                ["ros2", "run", "pdsmc_ros", "controller", "--ros-args", "-p", f"type:={law}", "-p", "robot:=ur5",
                 "-p", "mode:=realtime", "-p", "rate:=1000.0"], env=env, stdout=out, stderr=subprocess.STDOUT))
        client = Client(domain, names)
        try:
            if not client.action.wait_for_server(timeout_sec=90):
                raise RuntimeError(f"{law}: no action server (logs in {logs})")
            deadline = time.monotonic() + 30
            while not client.states and time.monotonic() < deadline:
                time.sleep(0.05)
            deadline = time.monotonic() + 60
            while time.monotonic() < deadline:  # the controller has a joint state: a goal staying put is accepted
                here = client.q()
                stay = goal(names, here, here, seconds=0.1)
                handle = client.call(lambda stay=stay: client.action.send_goal_async(stay))
                if handle is not None and handle.accepted:
                    client.call(lambda handle=handle: handle.get_result_async(), 10.0)
                    break
                time.sleep(0.5)
            else:
                raise RuntimeError(f"{law}: every goal refused for 60 s (logs in {logs})")
            time.sleep(1.0)  # the hold settles
            yield client
        finally:
            client.close()
    finally:
        for proc in procs:
            proc.send_signal(2)
        for proc in procs:
            try:
                proc.wait(timeout=20)
            except subprocess.TimeoutExpired:
                proc.kill()


def worst_of(velocities: np.ndarray, limits: np.ndarray, names: list[str]) -> tuple[float, str]:
    """The largest ``|qd_i| / v_max_i`` and its joint (nan, '': no states)."""
    if not velocities.size:
        return float("nan"), ""
    ratios = np.abs(velocities) / limits
    joint = int(np.argmax(np.max(ratios, axis=0)))
    return float(np.max(ratios)), names[joint]


def bench_law(law: str, names: list[str], limits: np.ndarray, goals: int, domain: int, env: dict[str, str],
              logs: Path) -> dict[str, Row]:
    bag = logs / f"{law}-bag"
    ends: dict[str, list[tuple[str, float]]] = {}
    with running(law, names, domain, env, logs, bag=bag) as client:
        t0 = time.time()
        sign = 1.0
        for ending in ENDINGS:
            for _ in range(goals):
                outcome, ended = run_goal(client, names, ending, sign)
                ends.setdefault(ending, []).append((outcome, ended))
                sign = -sign
                time.sleep(AFTER_S)
        t1 = time.time()
        time.sleep(0.5)  # the recorder writes the last states
    stamps, _, qd = recorded_states(bag, names)
    rows: dict[str, Row] = {}
    for ending, goals_ended in ends.items():
        worst, joint = 0.0, ""
        for _, ended in goals_ended:
            window = (stamps >= ended) & (stamps <= ended + AFTER_S)
            ratio, on = worst_of(qd[window], limits, names)
            if not ratio <= worst:  # nan (no states) shows
                worst, joint = ratio, on
        rows[ending] = (worst, joint, [outcome for outcome, _ in goals_ended])
    span = (stamps >= t0) & (stamps <= t1)
    rows["whole run"] = (*worst_of(qd[span], limits, names), [])
    gaps = np.diff(stamps[span]) if np.count_nonzero(span) > 1 else np.zeros(1)
    print(f"{law:8s} states {np.count_nonzero(span)} of {int((t1 - t0) * 1000)} at 1 kHz in the bag "
          f"(largest gap {np.max(gaps) * 1e3:.1f} ms)", flush=True)
    return rows


def load() -> str:
    return " ".join(f"{v:.2f}" for v in os.getloadavg())


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--laws", default="pd,smc,pdsmc")
    parser.add_argument("--goals", type=int, default=10)
    parser.add_argument("--busy", action="store_true", help="keep one core busy with another process")
    parser.add_argument("--domain", type=int, default=77)
    args = parser.parse_args()
    robot = make_robot(resolve_robot("ur5"))
    names, limits = list(robot.joint_names), np.asarray(robot.velocity_limits, dtype=float)
    env = dict(os.environ, ROS_DOMAIN_ID=str(args.domain), ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST")
    logs = Path(f"/tmp/goal_ends-{os.getpid()}")
    logs.mkdir(parents=True, exist_ok=True)
    busy = subprocess.Popen([sys.executable, "-c", "while True: pass"]) if args.busy else None
    worst_after = worst = 0.0
    try:
        for law in args.laws.split(","):
            print(f"{law:8s} start: load average {load()}", flush=True)
            rows = bench_law(law, names, limits, args.goals, args.domain, env, logs)
            for ending, (ratio, joint, how) in rows.items():
                counts = {k: how.count(k) for k in dict.fromkeys(how)}
                print(f"{law:8s} {ending:15s} largest |qd|/v_max {ratio:.3f} ({joint})  {counts}", flush=True)
                if ending == "whole run":
                    worst = max(worst, ratio)
                else:
                    worst_after = max(worst_after, ratio)
            print(f"{law:8s} end: load average {load()}", flush=True)
    finally:
        if busy is not None:
            busy.kill()
    print(f"worst_after_end_ratio={worst_after:.3f} worst_ratio={worst:.3f}  (logs: {logs})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
