"""Benchmark: the ordinary real-time run on this machine -- tracking against offline, the hold, the
command rate, goals from the first moment (issue 54).

The check a user runs first. MuJoCo stands in for the thesis serial 3R at 1 kHz of wall time
(``ros2 run pdsmc_ros mujoco_driver``: its own Python loop, wall-clock stamps, a driver's joint
order); the controller runs as shipped (``type:=pd``, ``mode:=realtime``, 1 kHz, gains stable at
1 kHz with the loop's delay; every real-time setting at its default); a plain rclpy client in this
process drives both. Every other run gives the controller its ``joints`` in another order than the
arm's. In each run:

1. **The first goal.** As soon as the client sees the action server it sends a goal that stays where
   the arm is (0.5 s), again every 20 ms until one is accepted: the time from the server's appearance
   to the acceptance, and how many were refused.
2. **The hold.** The 2 s from the controller's first command (the arm braked until then; the first
   goal stays where the arm is): the largest distance of any joint from where the arm was when the
   controller took it (``drift``, mrad) and the effort commands the client received in those 2 s
   (``commands``, against the 2,000 the rate asks for; a Python client on a loaded machine drops
   some: the controller's own count of missed deadlines over the run, from its ``/diagnostics``,
   is printed beside it).
3. **One trajectory on** ``~/joint_trajectory``, stamped 0 (start on receipt): a 2 s quintic of
   joints 1 and 2 by 0.4 and 0.2 rad. Its error is measured against the reference timed from the
   moment the client published it, over the motion and 0.5 s after, and divided by the same error
   of an offline run (the same PD, gains and model, against the same MuJoCo arm in lockstep,
   :mod:`pdsmc_ros.sim.mujoco_lockstep`, from the same measured start): ``ratio``.
4. **Three goals**: back to the start in 2 s (expected SUCCEEDED), a 0.5 rad move in 0.1 s with a
   0.01 rad path tolerance (expected ABORTED: PATH_TOLERANCE_VIOLATED), and a 3 s move canceled
   after 0.5 s (expected CANCELED).

The 1 kHz topics are taken by a client node of their own (a thread and a DDS participant apart
from the one that sends goals), so a burst of action traffic does not hold them back. ``--busy``
keeps one core busy with another process throughout (robot computers are never idle);
``--prefix VENV`` runs the nodes of another install (``VENV/bin/ros2``: a tree before a change,
for a paired comparison; the offline run is this tree's); ``--param NAME:=VALUE`` adds a
controller parameter.

Targets (issue 54): quiet, ratio within 1.1 in every run; one core busy, within 1.5; drift under
10 mrad; at least 99 % of the commands; every goal as expected.

Last line: ``runs=N ratio_max=R within_1.1=A within_1.5=B drift_max_mrad=D commands_min=C
goals_as_expected=G first_goal_median_s=F first_goal_max_s=M``.

Usage: python bench/ordinary_run.py [--runs 10] [--busy] [--prefix VENV] [--param NAME:=VALUE ...]
(inside the venv, after make setup)
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from action_msgs.msg import GoalStatus  # noqa: E402
from builtin_interfaces.msg import Duration  # noqa: E402
from control_msgs.action import FollowJointTrajectory  # noqa: E402
from control_msgs.msg import JointTolerance  # noqa: E402
from diagnostic_msgs.msg import DiagnosticArray  # noqa: E402
from rclpy.action import ActionClient  # noqa: E402
from rclpy.qos import QoSProfile, ReliabilityPolicy  # noqa: E402
from sensor_msgs.msg import JointState  # noqa: E402
from std_msgs.msg import Float64MultiArray  # noqa: E402
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint  # noqa: E402

from pdsmc_ros.ros.spun_node import SpunNode, wait_until  # noqa: E402

NAMES = ["joint1", "joint2", "joint3"]
KP = [1200.0, 1200.0, 240.0]  # stable at 1 kHz with the real-time loop's two periods of delay
KD = [60.0, 60.0, 12.0]
RATE = 1000.0
HOLD_S = 2.0
SPAN_S = 2.0
MOVE = np.array([0.4, 0.2, 0.0])
AFTER_S = 0.5  # the error window goes on this long after the trajectory's end
EXPECTED = {"reachable": (GoalStatus.STATUS_SUCCEEDED, 0),
            "too fast": (GoalStatus.STATUS_ABORTED, FollowJointTrajectory.Result.PATH_TOLERANCE_VIOLATED),
            "canceled": (GoalStatus.STATUS_CANCELED, 0)}


def duration(seconds: float) -> Duration:
    return Duration(sec=int(seconds), nanosec=int(round((seconds % 1.0) * 1e9)))


def quintic(q0: np.ndarray, q1: np.ndarray, span: float, t: np.ndarray) -> np.ndarray:
    """Positions, velocities and accelerations (``(len(t), 3, n)``) of the rest-to-rest quintic."""
    s = np.clip(t / span, 0.0, 1.0)[:, None]
    inside = ((t >= 0) & (t <= span))[:, None]
    d = q1 - q0
    q = q0 + d * (10 * s**3 - 15 * s**4 + 6 * s**5)
    qd = d * (30 * s**2 - 60 * s**3 + 30 * s**4) / span * inside
    qdd = d * (60 * s - 180 * s**2 + 120 * s**3) / span**2 * inside
    return np.stack([q, qd, qdd], axis=1)


def points(q0: np.ndarray, q1: np.ndarray, span: float, order: list[int]) -> list[JointTrajectoryPoint]:
    zero = [0.0] * len(q0)
    return [JointTrajectoryPoint(positions=[float(q0[i]) for i in order], velocities=zero, accelerations=zero,
                                 time_from_start=duration(0.0)),
            JointTrajectoryPoint(positions=[float(q1[i]) for i in order], velocities=zero, accelerations=zero,
                                 time_from_start=duration(span))]


class Watch(SpunNode):
    """The 1 kHz topics: every joint state (stamp, q by :data:`NAMES`) and every command's arrival."""

    def __init__(self, domain: int) -> None:
        super().__init__(domain, "ordinary_run_watch")
        self.lock = threading.Lock()
        self.states: list[tuple[float, np.ndarray]] = []
        self.commands: list[float] = []
        deep = QoSProfile(depth=2000, reliability=ReliabilityPolicy.BEST_EFFORT)
        self.node.create_subscription(JointState, "/joint_states", self.on_state, deep)
        # the newest state alone (the deep queue's may lag behind on a loaded machine): where a goal starts
        self.latest: np.ndarray | None = None
        self.node.create_subscription(JointState, "/joint_states", self.on_latest, 1)
        # the controller's own count of its ticks and missed deadlines (its loop statistics, once a second)
        self.loop: dict[str, str] = {}
        self.node.create_subscription(DiagnosticArray, "/diagnostics", self.on_diagnostics, 50)
        self.node.create_subscription(Float64MultiArray, "/effort_controller/commands", self.on_command, deep)

    def on_state(self, msg: JointState) -> None:
        index = [list(msg.name).index(n) for n in NAMES]
        with self.lock:
            self.states.append((msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9,
                                np.asarray(msg.position)[index]))

    def on_diagnostics(self, msg: DiagnosticArray) -> None:
        for status in msg.status:
            values = {kv.key: kv.value for kv in status.values}
            if status.name.startswith("controller") and "missed_pct" in values:
                self.loop = values

    def on_latest(self, msg: JointState) -> None:
        self.latest = np.asarray(msg.position)[[list(msg.name).index(n) for n in NAMES]]

    def on_command(self, msg: Float64MultiArray) -> None:
        now = time.time()
        with self.lock:
            self.commands.append(now)

    def q(self) -> np.ndarray:
        latest = self.latest
        if latest is not None:
            return latest.copy()
        with self.lock:
            return self.states[-1][1].copy()

    def taken_until(self, stamp: float, seconds: float = 10.0) -> bool:
        """Wait until a state stamped after ``stamp`` has been taken (the window before it is complete)."""
        return wait_until(lambda: bool(self.states) and self.states[-1][0] > stamp, seconds)

    def window(self, start: float, end: float) -> tuple[np.ndarray, np.ndarray]:
        with self.lock:
            rows = [s for s in self.states if start <= s[0] <= end]
        return np.array([r[0] for r in rows]), np.array([r[1] for r in rows]).reshape(-1, len(NAMES))

    def commands_between(self, start: float, end: float) -> int:
        with self.lock:
            return sum(1 for t in self.commands if start <= t <= end)


class Goals(SpunNode):
    """The client that sends the trajectory and the goals (its own participant)."""

    def __init__(self, domain: int) -> None:
        super().__init__(domain, "ordinary_run_client")
        self.trajectory = self.node.create_publisher(JointTrajectory, "/controller/joint_trajectory", 10)
        self.action = ActionClient(self.node, FollowJointTrajectory, "/controller/follow_joint_trajectory")

    def goal(self, names: list[str], order: list[int], q0: np.ndarray, q1: np.ndarray, span: float,
             path: float | None = None) -> FollowJointTrajectory.Goal:
        tolerances = [] if path is None else [JointTolerance(name=n, position=path) for n in names]
        return FollowJointTrajectory.Goal(trajectory=JointTrajectory(joint_names=names,
                                                                     points=points(q0, q1, span, order)),
                                          path_tolerance=tolerances)

    def send(self, goal: FollowJointTrajectory.Goal) -> object | None:
        handle = self.call(lambda: self.action.send_goal_async(goal), 10.0)
        return handle if handle is not None and handle.accepted else None  # type: ignore[attr-defined]

    def result(self, handle: object, seconds: float = 15.0) -> tuple[int, int, str]:
        answer = self.call(handle.get_result_async, seconds)  # type: ignore[attr-defined]
        if answer is None:
            return -1, 0, "no result"
        return answer.status, answer.result.error_code, answer.result.error_string


def offline_error(q0: np.ndarray, t: np.ndarray) -> float:
    """Mean |e| (rad, over the joints and ``t``: s after the trajectory's start) of the same PD against
    the same MuJoCo arm in lockstep from rest at ``q0``."""
    from pdsmc_ros.control.law import ControlLaw
    from pdsmc_ros.control.registry import Gains
    from pdsmc_ros.runs.builder import make_run
    from pdsmc_ros.sim.mujoco_lockstep import StandIn

    spec = make_run("serial_3r", "circle", "pd", rate=RATE, gains=Gains.from_mapping({"kp": KP, "kd": KD}, 3, "pd"))
    robot = spec.robot_model()
    steps = int(round((SPAN_S + AFTER_S) * RATE))
    refs = np.ascontiguousarray(quintic(q0, q0 + MOVE, SPAN_S, np.arange(steps + 1) / RATE))
    loop = StandIn().loop("serial_3r", RATE, robot)
    out_q, _, _, outcome = loop(robot, ControlLaw.from_spec(spec), q0, refs, 1.0 / RATE, 1, every_step=True)
    reference = quintic(q0, q0 + MOVE, SPAN_S, np.arange(steps + 1) / RATE)[:, 0]
    inside = np.arange(steps + 1) / RATE <= t.max()
    return float(np.mean(np.abs(out_q - reference)[inside]))


def one_run(index: int, args: argparse.Namespace, env: dict[str, str], logs: Path) -> dict[str, object]:
    domain = args.domain + index
    env = dict(env, ROS_DOMAIN_ID=str(domain))
    joints = NAMES if index % 2 == 0 else ["joint3", "joint1", "joint2"]
    order = [NAMES.index(j) for j in joints]
    prefix = Path(args.prefix or sys.prefix)
    ros2 = str(prefix / "bin" / "ros2")
    env = dict(env, PATH=f"{prefix / 'bin'}{os.pathsep}{env.get('PATH', '')}", AMENT_PREFIX_PATH=str(prefix))
    params = [p for given in args.param for p in ("-p", given)]
    procs: list[subprocess.Popen[bytes]] = []
    run: dict[str, object] = {"run": index, "joints": ",".join(joints)}
    watch = goals = None
    try:
        with open(logs / f"run{index}-driver.log", "w") as out:
            # its effort controller takes data[i] for joints[i], as the controller's commands are given; its
            # joint states stay in the arm's order
            procs.append(subprocess.Popen([ros2, "run", "pdsmc_ros", "mujoco_driver", "--ros-args", "-p",
                                           "robot:=serial_3r", "-p", f"rate:={RATE}", "-p", f"joints:={joints}"],
                                          env=env, stdout=out, stderr=subprocess.STDOUT))
        watch = Watch(domain)
        goals = Goals(domain)
        if not wait_until(lambda: len(watch.states) > 50, 60):
            raise RuntimeError("no joint states from the stand-in in 60 s")
        with open(logs / f"run{index}-controller.log", "w") as out:
            procs.append(subprocess.Popen(
                [ros2, "run", "pdsmc_ros", "controller", "--ros-args", "-p", "robot:=serial_3r", "-p", "type:=pd",
                 "-p", "mode:=realtime", "-p", f"rate:={RATE}", "-p", f"sample_rate:={RATE}",
                 "-p", f"joints:={joints}", "-p", f"kp:={[KP[i] for i in order]}",
                 "-p", f"kd:={[KD[i] for i in order]}", *params],
                env=env, stdout=out, stderr=subprocess.STDOUT))
        if not wait_until(lambda: bool(watch.commands), 90):
            raise RuntimeError("no effort command in 90 s")
        commanding = watch.commands[0]
        watch.taken_until(commanding)
        _, braked_q = watch.window(commanding - 0.5, commanding)
        if not braked_q.size:
            raise RuntimeError("no joint state in the 0.5 s before the first command")
        held = braked_q[-1]  # where the arm was when the controller took it: what its hold holds
        if not goals.action.wait_for_server(timeout_sec=90):
            from rclpy.action import get_action_names_and_types
            raise RuntimeError(f"no action server in 90 s (the graph's actions: "
                               f"{get_action_names_and_types(goals.node)})")
        appeared, tries, handle = time.monotonic(), 0, None
        while handle is None and time.monotonic() - appeared < 30:
            here = watch.q()
            tries += 1
            handle = goals.send(goals.goal(joints, order, here, here, 0.5))
            if handle is None:
                time.sleep(0.02)
        run["first_goal_s"] = time.monotonic() - appeared if handle is not None else float("inf")
        run["first_goal_tries"] = tries
        if handle is None:
            raise RuntimeError("no goal accepted in 30 s after the server appeared")
        goals.result(handle)
        # the hold: the activation's, 2 s from the first command (the first goal stayed where the arm was)
        held_to = commanding + HOLD_S
        time.sleep(max(0.0, held_to - time.time()))
        watch.taken_until(held_to)
        _, q = watch.window(commanding, held_to)
        run["drift_mrad"] = float(np.max(np.abs(q - held)) * 1e3) if q.size else float("nan")
        run["commands"] = watch.commands_between(commanding, held_to)
        # the trajectory on ~/joint_trajectory, stamped 0
        q0 = watch.q()
        msg = JointTrajectory(joint_names=joints, points=points(q0, q0 + MOVE, SPAN_S, order))
        published = time.time()
        goals.trajectory.publish(msg)
        time.sleep(SPAN_S + AFTER_S + 0.2)
        watch.taken_until(published + SPAN_S + AFTER_S)
        t, q = watch.window(published, published + SPAN_S + AFTER_S)
        if not q.size:
            raise RuntimeError("no joint states while the trajectory ran")
        reference = quintic(q0, q0 + MOVE, SPAN_S, t - published)[:, 0]
        measured = float(np.mean(np.abs(q - reference)))
        offline = offline_error(q0, t - published)
        run["error_mrad"], run["offline_mrad"] = measured * 1e3, offline * 1e3
        run["ratio"] = measured / offline
        # the three goals, from where the trajectory ended
        start = watch.q()
        outcomes = {}
        for name, step, span, path in (("reachable", None, 2.0, 0.5), ("too fast", [0.5, 0.0, 0.0], 0.1, 0.01),
                                       ("canceled", -MOVE, 3.0, None)):
            here = watch.q()
            target = start - MOVE if step is None else here + step
            handle = goals.send(goals.goal(joints, order, here, target, span, path))
            if handle is None:
                outcomes[name] = "rejected"
                continue
            if name == "canceled":
                time.sleep(0.5)
                goals.call(handle.cancel_goal_async, 10.0)  # type: ignore[attr-defined]
            status, code, why = goals.result(handle)
            outcomes[name] = "as expected" if (status, code) == EXPECTED[name] else f"{status}/{code} {why}"
            time.sleep(0.5)
        run["goals"] = outcomes
        run["goals_ok"] = all(v == "as expected" for v in outcomes.values())
        run["missed_pct"] = float(watch.loop.get("missed_pct", "nan"))
    except RuntimeError as exc:
        run["error"] = str(exc)
        run.setdefault("first_goal_s", float("inf"))
    finally:
        for node in (goals, watch):
            if node is not None:
                node.close()
        for proc in reversed(procs):
            proc.send_signal(2)
        for proc in reversed(procs):
            try:
                proc.wait(timeout=20)
            except subprocess.TimeoutExpired:
                proc.kill()
    return run


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=10)
    parser.add_argument("--busy", action="store_true", help="keep one core busy with another process")
    parser.add_argument("--prefix", default="", help="the venv whose nodes run (default: this one's)")
    parser.add_argument("--param", action="append", default=[], metavar="NAME:=VALUE",
                        help="a controller parameter (repeatable)")
    parser.add_argument("--domain", type=int, default=160, help="the first run's ROS domain (one per run)")
    args = parser.parse_args()
    if args.runs < 1:
        parser.error(f"--runs must be at least 1, got {args.runs}")
    if args.prefix and not (Path(args.prefix) / "bin" / "ros2").exists():
        parser.error(f"--prefix: no bin/ros2 in {args.prefix!r} (a venv made by make setup)")
    env = dict(os.environ)
    logs = Path(tempfile.mkdtemp(prefix="ordinary_run-"))
    busy = subprocess.Popen([sys.executable, "-c", "while True: pass"]) if args.busy else None
    runs = []
    try:
        for index in range(args.runs):
            run = one_run(index, args, env, logs)
            runs.append(run)
            if "error" in run:
                print(f"run {index} ({run['joints']}): failed: {run['error']}", flush=True)
                continue
            print(f"run {index} ({run['joints']}): ratio {run['ratio']:.3f} (error {run['error_mrad']:.2f} mrad, "
                  f"offline {run['offline_mrad']:.2f}), drift {run['drift_mrad']:.1f} mrad, "
                  f"commands {run['commands']} in {HOLD_S:g} s (the controller's missed deadlines over the run "
                  f"{run['missed_pct']:.2f} %), first goal {run['first_goal_s']:.3f} s "
                  f"({run['first_goal_tries']} tries), goals {run['goals']}", flush=True)
    finally:
        if busy is not None:
            busy.kill()
    done = [r for r in runs if "error" not in r]
    ratios = np.array([float(r["ratio"]) for r in done] or [np.inf])
    first = np.array([float(r["first_goal_s"]) for r in runs])
    print(f"runs={len(runs)} ratio_max={ratios.max():.3f} within_1.1={int(np.sum(ratios <= 1.1))} "
          f"within_1.5={int(np.sum(ratios <= 1.5))} "
          f"drift_max_mrad={max([float(r['drift_mrad']) for r in done] or [np.nan]):.1f} "
          f"commands_min={min([int(r['commands']) for r in done] or [0])} "  # type: ignore[call-overload]
          f"missed_pct_max={max([float(r['missed_pct']) for r in done] or [np.nan]):.2f} "
          f"goals_as_expected={sum(1 for r in done if r['goals_ok'])} "
          f"first_goal_median_s={np.median(first):.3f} first_goal_max_s={first.max():.3f}  (logs: {logs})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
