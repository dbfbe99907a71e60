"""The MuJoCo stand-in and the controller in real time, and a plain rclpy client of them.

What the real-time end-to-end tests on the stand-in share (test_bench_ur5_e2e.py,
test_position_domain_e2e.py, test_jtc_conformance.py): the two nodes started as processes in a DDS
domain of their own (conftest's next_domain), their output in ``driver.log`` and ``controller.log``,
stopped by PID (conftest's stop_process); the client's joint states in the test's joint order, the
newest position, the count of the controller's state messages (it publishes them once it commands),
its ``FollowJointTrajectory`` action, and the nodes' log tails for a failure's message.
"""

from __future__ import annotations

import subprocess
import threading
import time
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np
from builtin_interfaces.msg import Duration
from conftest import next_domain, stop_process
from control_msgs.action import FollowJointTrajectory
from control_msgs.msg import JointTrajectoryControllerState
from rclpy.action import ActionClient
from sensor_msgs.msg import JointState

from pdsmc_ros.ros.spun_node import SpunNode

COMMON = ["--ros-args", "-p", "thread_priority:=0"]  # a shared 2-core machine: no SCHED_FIFO spinning


def duration(seconds: float) -> Duration:
    return Duration(sec=int(seconds // 1), nanosec=int(round((seconds % 1.0) * 1e9)) % 1_000_000_000)


class StandInArm(SpunNode):
    """``mujoco_driver`` and ``controller`` (processes, with ``driver`` and ``controller`` their parameters
    after :data:`COMMON`) and a client node ``name`` of them.

    ``states`` holds ``(monotonic s, q, qd)`` in the order of ``joints``, the newest ``keep``.
    """

    def __init__(self, ros_env: dict, log_dir: Path, name: str, joints: Sequence[str], *,
                 driver: Sequence[str], controller: Sequence[str], keep: int = 5000) -> None:
        self.domain = next_domain()
        self.log_dir = log_dir
        self.joints = list(joints)
        self.keep = keep
        env = dict(ros_env, ROS_DOMAIN_ID=str(self.domain))
        self.procs = [
            subprocess.Popen(["ros2", "run", "pdsmc_ros", "mujoco_driver", *COMMON, *driver],
                             env=env, stdout=(log_dir / "driver.log").open("w"), stderr=subprocess.STDOUT,
                             start_new_session=True),
            subprocess.Popen(["ros2", "run", "pdsmc_ros", "controller", *COMMON, *controller],
                             env=env, stdout=(log_dir / "controller.log").open("w"), stderr=subprocess.STDOUT,
                             start_new_session=True)]
        try:
            super().__init__(self.domain, name)
        except BaseException:  # the client did not start: the processes are this test's to stop
            for proc in self.procs:
                stop_process(proc)
            raise
        self.lock = threading.Lock()
        self.states: list[tuple[float, np.ndarray, np.ndarray]] = []
        # the newest state only: a Python client on a loaded machine may take fewer than 1,000 a second
        self.node.create_subscription(JointState, "/joint_states", self.on_state, 1)
        self.controller_states = 0  # the controller publishes its state once it commands
        self.node.create_subscription(JointTrajectoryControllerState, "/controller/controller_state",
                                      self.on_controller_state, 1)
        self.action = ActionClient(self.node, FollowJointTrajectory, "/controller/follow_joint_trajectory")

    def in_order(self, msg: JointState, field: str) -> np.ndarray:
        """``msg``'s ``field`` (position, velocity) in the order of :attr:`joints`."""
        names = list(msg.name)
        values = getattr(msg, field)
        return np.array([values[names.index(j)] for j in self.joints], dtype=float)

    def on_state(self, msg: JointState) -> None:
        q, qd = self.in_order(msg, "position"), self.in_order(msg, "velocity")
        with self.lock:
            self.states.append((time.monotonic(), q, qd))
            del self.states[:-self.keep]

    def on_controller_state(self, _msg: JointTrajectoryControllerState) -> None:
        self.controller_states += 1

    def q(self) -> np.ndarray:
        """The newest position."""
        with self.lock:
            return self.states[-1][1].copy()

    def up(self, server_s: float = 120.0) -> bool:
        """Whether the driver publishes, the action server answers and the controller commands."""
        return (self.wait(lambda: len(self.states) > 100, 90) and self.action.wait_for_server(timeout_sec=server_s)
                and self.wait(lambda: self.controller_states > 5, 180))

    def logs(self) -> str:
        """The tail of each node's output, for a failure's message."""
        return "\n".join(f"--- {p.name}\n{p.read_text()[-4000:]}" for p in sorted(self.log_dir.glob("*.log")))

    def call(self, make: Callable[[], object], seconds: float = 30.0, why: Callable[[], str] | None = None) -> object:
        """A request sent while the spin thread is paused; no answer fails with the nodes' logs."""
        return super().call(make, seconds, why or self.logs)

    def close(self) -> None:
        super().close()
        for proc in reversed(self.procs):
            stop_process(proc)
