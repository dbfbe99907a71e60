"""Types as a test (ros2 packages carry test_mypy): mypy --strict on the ROS-free core (setup.cfg)."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
# the core: everything but the rclpy nodes and the command-line front ends
CORE = ["pdsmc_ros/bag", "pdsmc_ros/robots", "pdsmc_ros/control", "pdsmc_ros/sim",
        "pdsmc_ros/config.py", "pdsmc_ros/errors.py", "pdsmc_ros/metrics/statistics.py",
        "pdsmc_ros/runs", "pdsmc_ros/contours", "pdsmc_ros/viewer/live_view.py",
        "pdsmc_ros/kernels/cache.py", "pdsmc_ros/parameters/params_file.py", "pdsmc_ros/parameters/run_table.py",
        "pdsmc_ros/parameters/joint_map.py",
        # the components' ROS-free decisions
        *(f"pdsmc_ros/controller/{m}.py" for m in ("core", "commanding", "goals", "joint_trajectory", "hold",
                                                   "joints", "limits",
                                                   "sidecar/framing", "sidecar/process", "sidecar/gain_check")),
        "pdsmc_ros/trajectory/reference_windows.py", "pdsmc_ros/loop/realtime.py", "pdsmc_ros/loop/statistics.py",
        "pdsmc_ros/resources.py", "pdsmc_ros/metrics/scores.py", "pdsmc_ros/experiments",
        "pdsmc_ros/identification"]


def mypy() -> list[str]:
    found = shutil.which("mypy", path=str(Path(sys.executable).parent))
    if found is None:
        pytest.fail("mypy is not installed in this environment (make setup installs requirements-test.txt)")
    return [found]


@pytest.mark.timeout(300)
def test_the_core_is_strictly_typed() -> None:
    proc = subprocess.run([*mypy(), "--config-file", "setup.cfg", "--cache-dir", "/dev/null", *CORE],
                          cwd=ROOT, capture_output=True, text=True, timeout=280)
    assert proc.returncode == 0, proc.stdout[-4000:] + proc.stderr


def test_strict_mode_catches_an_untyped_function(tmp_path: Path) -> None:
    bad = tmp_path / "bad.py"
    bad.write_text("def f(x):\n    return x\n")
    proc = subprocess.run([*mypy(), "--config-file", str(ROOT / "setup.cfg"), "--cache-dir", "/dev/null", str(bad)],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 1 and "no-untyped-def" in proc.stdout, proc.stdout + proc.stderr
