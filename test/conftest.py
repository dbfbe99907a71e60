"""Shared fixtures: locating the installed ROS entry points for end-to-end tests, ROS domains of
their own, a plain rclpy node."""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

ROOT = Path(__file__).resolve().parent.parent

# ROS domains (Fast DDS allows 0-232): each test that starts participants takes the next one, so
# no two tests of a session share a domain; a session starts at an offset of its own (another
# session on this machine, e.g. a fresh-clone check, most likely uses other domains)
_DOMAIN_COUNTER = iter(range(os.getpid() % 116 * 2, 10**9))


def next_domain() -> int:
    """A ROS domain id no other test of this session has used (until 232 have been used)."""
    return next(_DOMAIN_COUNTER) % 232 + 1


@pytest.fixture(scope="session")
def ros_env() -> dict[str, str]:
    """Environment in which `ros2 run pdsmc_ros ...` and the orchestration work.

    Skips the test when rclpy or the installed executables are missing (the
    core tests never need them).
    """
    pytest.importorskip("rclpy")
    prefix = Path(sys.prefix)
    ros2 = prefix / "bin" / "ros2"
    if not ros2.exists() or not (prefix / "lib" / "pdsmc_ros" / "plant").exists():
        pytest.skip("pdsmc_ros is not installed in this environment (run `make setup`)")
    env = dict(os.environ)
    env["PATH"] = f"{prefix / 'bin'}{os.pathsep}{env.get('PATH', '')}"
    env["AMENT_PREFIX_PATH"] = str(prefix)
    env.setdefault("NUMBA_CACHE_DIR", str(prefix / "numba-cache"))
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    assert shutil.which("ros2", path=env["PATH"])
    return env


def node_log_tails(out: Path, lines: int = 25) -> str:
    """The last lines of every node log of an orchestrated run (for failure messages)."""
    logs = Path(f"{out}.logs")
    parts = []
    for log in sorted(logs.glob("*.log")) if logs.is_dir() else []:
        tail = log.read_text(errors="replace").splitlines()[-lines:]
        parts.append(f"--- {log.name} (last {len(tail)} lines)\n" + "\n".join(tail))
    return "\n".join(parts) or f"(no node logs in {logs})"


def stop_process(proc: subprocess.Popen, *, grace_s: float = 20.0) -> tuple[int, str]:
    """End a process the test started, by its PID: SIGINT (a node's clean stop), SIGKILL if it has
    not ended after ``grace_s``. Returns its exit status and its piped output ("" if not piped)."""
    if proc.poll() is None:
        os.kill(proc.pid, signal.SIGINT)
    try:
        out, _ = proc.communicate(timeout=grace_s)
    except subprocess.TimeoutExpired:
        os.kill(proc.pid, signal.SIGKILL)
        out, _ = proc.communicate(timeout=10)
    return proc.returncode, out or ""


@pytest.fixture
def rclpy_node(request: pytest.FixtureRequest) -> Iterator[Any]:
    """A plain rclpy node in a context and a ROS domain of its own (skipped without rclpy)."""
    rclpy = pytest.importorskip("rclpy")
    from rclpy.context import Context
    from rclpy.node import Node

    ctx = Context()
    rclpy.init(context=ctx, domain_id=next_domain())
    created = Node(f"{request.module.__name__.rsplit('.', 1)[-1]}_node", context=ctx)
    try:
        yield created
    finally:
        created.destroy_node()
        rclpy.shutdown(context=ctx)
