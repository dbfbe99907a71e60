"""``pdsmc send-goal`` against a plain rclpy FollowJointTrajectory server written here, and against the
project's controller on the MuJoCo stand-in: progress, the result, the exit status, Ctrl-C cancels.

Each test runs in a ROS domain of its own; the command is the tree's (``python -m pdsmc_ros.cli`` from
the checkout), a process the test starts and stops by PID.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest
from conftest import ROOT, next_domain, stop_process

pytest.importorskip("rclpy")
pytest.importorskip("control_msgs")
import rclpy  # noqa: E402
import rclpy.executors  # noqa: E402
from control_msgs.action import FollowJointTrajectory  # noqa: E402
from rclpy.action import ActionServer, CancelResponse, GoalResponse  # noqa: E402
from sensor_msgs.msg import JointState  # noqa: E402

from pdsmc_ros.contours.goal_file import goal_data, write_goal  # noqa: E402
from pdsmc_ros.ros.spun_node import SpunNode  # noqa: E402

ACTION = "/arm/follow_joint_trajectory"


class Server:
    """A plain FollowJointTrajectory server: ``behaviour`` says what it does with the next goal --
    ``succeed`` (three feedbacks, then SUCCESSFUL), ``abort`` (PATH_TOLERANCE_VIOLATED), ``reject``, or
    ``hold`` (feedback until canceled)."""

    def __init__(self, domain: int) -> None:
        self.context = rclpy.Context()
        rclpy.init(context=self.context, domain_id=domain)
        self.node = rclpy.create_node("plain_server", context=self.context)
        self.behaviour = "succeed"
        self.goals: list[FollowJointTrajectory.Goal] = []
        self.canceled = threading.Event()
        self.server = ActionServer(self.node, FollowJointTrajectory, ACTION, self.execute,
                                   goal_callback=self.on_goal, cancel_callback=lambda _: CancelResponse.ACCEPT,
                                   callback_group=rclpy.callback_groups.ReentrantCallbackGroup())
        self.executor = rclpy.executors.MultiThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.thread = threading.Thread(target=self._spin, daemon=True)
        self.thread.start()

    def _spin(self) -> None:
        while self.context.ok():
            self.executor.spin_once(timeout_sec=0.05)

    def on_goal(self, goal: FollowJointTrajectory.Goal) -> GoalResponse:
        self.goals.append(goal)
        return GoalResponse.REJECT if self.behaviour == "reject" else GoalResponse.ACCEPT

    def execute(self, handle):  # noqa: ANN001, ANN201
        result = FollowJointTrajectory.Result()
        for k in range(200 if self.behaviour == "hold" else 3):
            if handle.is_cancel_requested:
                self.canceled.set()
                handle.canceled()
                return result
            feedback = FollowJointTrajectory.Feedback(joint_names=list(handle.request.trajectory.joint_names))
            feedback.error.positions = [0.01 * (k + 1)] * len(feedback.joint_names)
            feedback.desired.time_from_start.sec = k
            handle.publish_feedback(feedback)
            time.sleep(1.1 if self.behaviour == "hold" else 0.6)
        if self.behaviour == "abort":
            result.error_code = FollowJointTrajectory.Result.PATH_TOLERANCE_VIOLATED
            result.error_string = "joint a path error 0.3"
            handle.abort()
            return result
        result.error_code = FollowJointTrajectory.Result.SUCCESSFUL
        handle.succeed()
        return result

    def close(self) -> None:
        self.server.destroy()
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)
        self.thread.join(timeout=5)


def send_goal(env: dict, domain: int, goal: Path, *extra: str) -> subprocess.Popen:
    # SIGINT as at a terminal: a suite started in the background by a shell runs with it ignored, which
    # its children inherit (and Python then raises no KeyboardInterrupt)
    return subprocess.Popen([sys.executable, "-m", "pdsmc_ros.cli", "send-goal", str(goal), *extra], cwd=ROOT,
                            env=dict(env, ROS_DOMAIN_ID=str(domain)), stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, start_new_session=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))


def finish(proc: subprocess.Popen, seconds: float = 90.0) -> tuple[int, str, str]:
    try:
        out, err = proc.communicate(timeout=seconds)
    except subprocess.TimeoutExpired:
        code, out = stop_process(proc)
        raise AssertionError(f"send-goal did not end within {seconds} s (exit {code}): {out}") from None
    return proc.returncode, out, err


@pytest.fixture
def plain(ros_env: dict, tmp_path: Path):  # noqa: ANN201
    domain = next_domain()
    server = Server(domain)
    goal = tmp_path / "goal.yaml"
    write_goal(goal, goal_data(["a", "b"], [1.0, 2.0], [[0.1, 0.2], [0.3, 0.4]]))
    yield server, goal, domain
    server.close()


@pytest.mark.timeout(180)
def test_against_a_plain_server(ros_env: dict, plain) -> None:  # noqa: ANN001
    server, goal, domain = plain
    code, out, err = finish(send_goal(ros_env, domain, goal, "--action", ACTION))
    assert code == 0, out + err
    assert "result: SUCCEEDED, error_code 0 (SUCCESSFUL)" in out
    assert "goal accepted" in err and "largest position error" in err
    sent = server.goals[-1].trajectory
    assert list(sent.joint_names) == ["a", "b"] and len(sent.points) == 2
    assert list(sent.points[1].positions) == pytest.approx([0.3, 0.4])
    assert sent.points[1].time_from_start.sec == 2

    server.behaviour = "abort"
    code, out, _ = finish(send_goal(ros_env, domain, goal, "--action", ACTION))
    assert code == 1 and "result: ABORTED, error_code -4 (PATH_TOLERANCE_VIOLATED): joint a path error 0.3" in out

    server.behaviour = "reject"
    code, out, _ = finish(send_goal(ros_env, domain, goal, "--action", ACTION))
    assert code == 1 and "goal rejected" in out

    code, out, _ = finish(send_goal(ros_env, domain, goal, "--action", "/nobody/follow_joint_trajectory",
                                    "--server-timeout", "2"))
    assert code == 1 and "goal no server: no FollowJointTrajectory server on /nobody" in out


@pytest.mark.timeout(180)
def test_ctrl_c_cancels_the_goal(ros_env: dict, plain) -> None:  # noqa: ANN001
    server, goal, domain = plain
    server.behaviour = "hold"
    proc = send_goal(ros_env, domain, goal, "--action", ACTION)
    deadline = time.monotonic() + 60
    while not server.goals and time.monotonic() < deadline:
        time.sleep(0.1)
    time.sleep(2.0)  # executing, feedback flowing
    # how the command takes signals, for a failure's message (ignored or blocked SIGINT: bit 2)
    signals = [line.strip() for line in Path(f"/proc/{proc.pid}/status").read_text().splitlines()
               if line.startswith(("SigBlk", "SigIgn", "SigCgt"))]
    os.kill(proc.pid, signal.SIGINT)
    try:
        code, out, err = finish(proc)
    except AssertionError as exc:
        raise AssertionError(f"{exc}\nthe command's signals before the SIGINT: {signals}") from None
    assert server.canceled.is_set()
    assert code == 130, out + err
    assert "result: CANCELED" in out and "canceling the goal" in err


HOLDING_SERVER = """
import sys, time
import rclpy, rclpy.executors
from control_msgs.action import FollowJointTrajectory
from rclpy.action import ActionServer, GoalResponse

rclpy.init()
node = rclpy.create_node("holding_server")

def execute(handle):
    print("executing", flush=True)
    while True:
        time.sleep(1.0)

server = ActionServer(node, FollowJointTrajectory, sys.argv[1], execute,
                      goal_callback=lambda goal: GoalResponse.ACCEPT)
rclpy.spin(node, executor=rclpy.executors.MultiThreadedExecutor())
"""


@pytest.mark.timeout(180)
def test_a_server_killed_during_the_goal_ends_the_wait(ros_env: dict, tmp_path: Path) -> None:
    """The server's process is SIGKILLed while it executes the goal: nothing will ever send the result,
    so the command must give up once the server has been gone ``--server-timeout`` seconds (exit 1,
    ``NO_RESULT``), not wait forever."""
    domain = next_domain()
    goal = tmp_path / "goal.yaml"
    write_goal(goal, goal_data(["a", "b"], [1.0, 2.0], [[0.1, 0.2], [0.3, 0.4]]))
    # the project's Fast DDS profile (scripts/run_experiment.sh's): a killed process is dropped after 2 s, not 20
    server_env = dict(ros_env, ROS_DOMAIN_ID=str(domain), FASTRTPS_DEFAULT_PROFILES_FILE=str(ROOT / "config" /
                                                                                              "fastdds_profile.xml"))
    server = subprocess.Popen([sys.executable, "-c", HOLDING_SERVER, ACTION], env=server_env, stdout=subprocess.PIPE,
                              stderr=subprocess.STDOUT, text=True, start_new_session=True)
    proc = None
    try:
        proc = send_goal(ros_env, domain, goal, "--action", ACTION, "--server-timeout", "10")
        assert server.stdout is not None
        line = server.stdout.readline()  # blocks until the goal executes (the test's timeout bounds it)
        assert line.strip() == "executing", line
        os.kill(server.pid, signal.SIGKILL)
        server.wait(timeout=10)
        code, out, err = finish(proc, seconds=120)
        assert code == 1, out + err
        assert "result: NO_RESULT" in out and "went away during the goal" in out, out
    finally:
        if proc is not None and proc.poll() is None:
            stop_process(proc)
        if server.poll() is None:
            stop_process(server)


def test_server_watch_waits_out_brief_absences() -> None:
    from pdsmc_ros.ros.goal_client import SERVER_CHECK_S, ServerWatch

    now = [0.0]
    present = [True]
    watch = ServerWatch(lambda: present[0], 2.0, clock=lambda: now[0])

    def run_for(seconds: float) -> bool:
        gone = False
        for _ in range(int(round(seconds / SERVER_CHECK_S))):
            now[0] += SERVER_CHECK_S
            gone = watch.gone()
        return gone

    assert not run_for(5.0)
    present[0] = False
    assert not run_for(1.5)  # away, not yet for 2 s
    present[0] = True
    assert not run_for(1.0)  # back: the count starts again
    present[0] = False
    assert not run_for(1.5)
    assert run_for(1.0)
    for bad in (-1.0, float("nan"), float("inf")):
        with pytest.raises(ValueError, match="patience must be"):
            ServerWatch(lambda: True, bad)


def test_a_bad_goal_file_is_refused_before_ros_starts(tmp_path: Path) -> None:
    from pdsmc_ros.cli import main

    bad = tmp_path / "goal.yaml"
    bad.write_text("trajectory: {joint_names: [a], points: []}\n")
    assert main(["send-goal", str(bad)]) == 2


# --- against the project's controller on the MuJoCo stand-in --------------------------------------
NAMES = ["joint1", "joint2", "joint3"]


def start(ros_env: dict, domain: int, log: Path, executable: str, *params: str) -> subprocess.Popen:
    args = ["ros2", "run", "pdsmc_ros", executable, "--ros-args", "-p", "thread_priority:=0", *params]
    return subprocess.Popen(args, env=dict(ros_env, ROS_DOMAIN_ID=str(domain)), stdout=log.open("w"),
                            stderr=subprocess.STDOUT, start_new_session=True)


@pytest.mark.timeout(300)
def test_against_the_projects_controller(ros_env: dict, tmp_path: Path) -> None:
    pytest.importorskip("mujoco")
    domain = next_domain()
    procs = [start(ros_env, domain, tmp_path / "driver.log", "mujoco_driver", "-p", "robot:=serial_3r"),
             start(ros_env, domain, tmp_path / "controller.log", "controller", "-p", "robot:=serial_3r",
                   "-p", "type:=pd", "-p", "mode:=realtime", "-p", "rate:=1000.0", "-p", "sample_rate:=1000.0",
                   "-p", "kp:=[1200.0, 1200.0, 240.0]", "-p", "kd:=[60.0, 60.0, 12.0]", "-p", "stale_periods:=200")]
    client = SpunNode(domain, "watcher")
    states: list[np.ndarray] = []
    client.node.create_subscription(JointState, "/joint_states", lambda m: states.append(
        np.array([dict(zip(m.name, m.position))[j] for j in NAMES])), 1)
    try:
        assert client.wait(lambda: len(states) > 50, 90), (tmp_path / "driver.log").read_text()
        q0 = states[-1]
        there = q0 + np.array([0.1, 0.0, 0.0])
        goal = tmp_path / "goal.yaml"
        write_goal(goal, goal_data(NAMES, [1.0, 2.0], [there, q0], [[0.0] * 3, [0.0] * 3]))
        for _ in range(20):  # the controller refuses goals until it is active (a second or two after start)
            code, out, err = finish(send_goal(ros_env, domain, goal))
            if "rejected" not in out:
                break
            time.sleep(1.0)
        logs = "\n".join(p.read_text()[-2000:] for p in sorted(tmp_path.glob("*.log")))
        assert code == 0, out + err + logs
        assert "result: SUCCEEDED, error_code 0 (SUCCESSFUL)" in out
        assert np.max(np.abs(states[-1] - q0)) < 0.02
    finally:
        client.close()
        for proc in reversed(procs):
            stop_process(proc)
