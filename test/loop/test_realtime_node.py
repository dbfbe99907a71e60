"""Real-time settings and loop statistics of a ticking node, seen from outside: the kernel's
view of the node's loop thread (policy, affinity, VmLck), its statistics on /diagnostics
counting a period we stall by stopping the process (SIGSTOP), and a node without the
privilege warning once and running on.

The trajectory node alone in real time ticks until it is stopped (no plant ever appears).
Each node runs a few seconds at a low SCHED_FIFO priority and is stopped by its PID.
"""

from __future__ import annotations

import os
import re
import shutil
import signal
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest
from conftest import next_domain, stop_process

rclpy = pytest.importorskip("rclpy")

from diagnostic_msgs.msg import DiagnosticArray  # noqa: E402
from rclpy.context import Context  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.node import Node  # noqa: E402

from pdsmc_ros.bag.loop_statistics import parse_values, status_name  # noqa: E402
from pdsmc_ros.loop.realtime import locked_kib, policy_of  # noqa: E402

NODE_ARGS = ["--ros-args", "-p", "mode:=realtime", "-p", "robot:=parallel_5r", "-p", "rate:=1000",
             "-p", "sample_rate:=500"]


class Listener:
    """A plain rclpy subscriber of /diagnostics in its own context (the test's participant)."""

    def __init__(self, domain: int) -> None:
        self.ctx = Context()
        rclpy.init(context=self.ctx, domain_id=domain)
        self.node = Node("statistics_listener", context=self.ctx)
        self.latest: dict[str, float] | None = None
        self.node.create_subscription(DiagnosticArray, "/diagnostics", self.on_message, 100)
        self.executor = SingleThreadedExecutor(context=self.ctx)
        self.executor.add_node(self.node)

    def on_message(self, msg: DiagnosticArray) -> None:
        for status in msg.status:
            if status.name == status_name("trajectory"):
                self.latest = parse_values({kv.key: kv.value for kv in status.values})

    def wait(self, until: float, ready: Callable[[dict[str, float]], bool]) -> dict[str, float] | None:
        """Spin until the latest statistics satisfy ``ready`` or ``until`` (monotonic) passes."""
        while time.monotonic() < until:
            self.executor.spin_once(timeout_sec=0.1)
            if self.latest is not None and ready(self.latest):
                return self.latest
        return self.latest

    def close(self) -> None:
        self.executor.shutdown(timeout_sec=1.0)
        self.node.destroy_node()
        rclpy.shutdown(context=self.ctx)


@pytest.fixture
def listener_env(ros_env: dict[str, str]) -> Iterator[tuple[Listener, dict[str, str]]]:
    domain = next_domain()
    env = dict(ros_env, ROS_DOMAIN_ID=str(domain))
    listener = Listener(domain)
    try:
        yield listener, env
    finally:
        listener.close()


def start_trajectory(env: dict[str, str], params: list[str], prefix: list[str] | None = None) -> subprocess.Popen:
    exe = Path(sys.prefix) / "lib" / "pdsmc_ros" / "trajectory"
    return subprocess.Popen([*(prefix or []), str(exe), *NODE_ARGS, *params], env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True)


def stop(proc: subprocess.Popen) -> str:
    if proc.poll() is None:
        os.kill(proc.pid, signal.SIGCONT)  # a test may have stopped it (SIGSTOP)
    return stop_process(proc)[1]


def privileged() -> bool:
    probe = "import os; os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(1))"
    return subprocess.run([sys.executable, "-c", probe], capture_output=True, timeout=30).returncode == 0


@pytest.mark.timeout(120)
def test_settings_hold_and_statistics_count_a_stalled_period(listener_env: tuple[Listener, dict[str, str]]) -> None:
    if not privileged():
        pytest.skip("this user may not set SCHED_FIFO")
    listener, env = listener_env
    proc = start_trajectory(env, ["-p", "thread_priority:=5", "-p", "cpu_affinity:=[0]"])
    out = ""
    try:
        first = listener.wait(time.monotonic() + 60, lambda v: v["ticks"] > 500)
        assert first is not None, "no loop statistics on /diagnostics"
        # the loop thread is the main thread (tid == pid): the kernel's view of it
        assert policy_of(proc.pid) == os.SCHED_FIFO
        assert os.sched_getparam(proc.pid).sched_priority == 5
        assert os.sched_getaffinity(proc.pid) == {0}
        assert locked_kib(Path(f"/proc/{proc.pid}/status")) > 0  # lock_memory: on by default in real time
        # the process's other threads (Fast DDS's, the executor's): FIFO below the loop, on its cores
        helpers = [int(t) for t in os.listdir(f"/proc/{proc.pid}/task") if int(t) != proc.pid]
        assert helpers
        for tid in helpers:
            assert policy_of(tid) == os.SCHED_FIFO and os.sched_getparam(tid).sched_priority == 1
            assert os.sched_getaffinity(tid) == {0}
        before = first["missed"]
        os.kill(proc.pid, signal.SIGSTOP)  # a deliberately stalled period: 0.3 s without a tick
        time.sleep(0.3)
        os.kill(proc.pid, signal.SIGCONT)
        after = listener.wait(time.monotonic() + 10, lambda v: v["ticks"] > first["ticks"] + 500)
        assert after is not None and after["ticks"] > first["ticks"]
        assert after["missed"] >= before + 1
        assert after["period_worst_us"] >= 0.25e6 and after["late_max_us"] >= 0.25e6
    finally:
        out = stop(proc)
    # at FIFO the default busy-wait is 50 us (a FIFO thread wakes on time), not the normal 200 us
    assert re.search(r"real time: SCHED_FIFO priority 5, cores 0, memory locked \(\d+ MiB reserved\), "
                     r"\d+ other threads at FIFO 1, busy-wait 50 us before each tick", out), out[-3000:]
    assert "running on without" not in out, out[-3000:]


@pytest.mark.timeout(120)
def test_a_node_without_the_privilege_warns_once_and_runs_on(listener_env: tuple[Listener, dict[str, str]]) -> None:
    setpriv = shutil.which("setpriv")
    if setpriv is None or not privileged():
        pytest.skip("needs setpriv and a privileged user to drop the capabilities from")
    listener, env = listener_env
    prefix = [setpriv, "--bounding-set=-sys_nice,-ipc_lock", "prlimit", "--rtprio=0", "--memlock=8388608", "--"]
    proc = start_trajectory(env, [], prefix)
    try:
        seen = listener.wait(time.monotonic() + 60, lambda v: v["ticks"] > 1000)
        assert seen is not None and seen["ticks"] > 1000, "the node did not run on"
        assert policy_of(proc.pid) == os.SCHED_OTHER
    finally:
        out = stop(proc)
    warnings = [line for line in out.splitlines() if "running on without" in line]
    assert len(warnings) == 1, out[-3000:]
    assert "CAP_SYS_NICE" in warnings[0] and "CAP_IPC_LOCK" in warnings[0] and "limits.conf" in warnings[0]
