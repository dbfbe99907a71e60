"""A new arm end to end (issue 29): tune -> check-gains -> a real-time run over DDS within limits, tracking.

The arm is written here (not taken from the project's config): four revolute joints, effort limits
40, 40, 20 and 6 N m, its options in a YAML beside the URDF, no preset gains.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml
from conftest import ROOT, next_domain, node_log_tails

EFFORT = (40.0, 40.0, 20.0, 6.0)


def write_arm(directory: Path) -> Path:
    """A yaw joint and three pitch joints in a vertical plane, a tool frame 0.1 m past the last."""
    def link(name: str, mass: float, com: str, inertia: float) -> str:
        return (f'  <link name="{name}"><inertial><origin xyz="{com}" rpy="0 0 0"/><mass value="{mass}"/>'
                f'<inertia ixx="{inertia}" ixy="0" ixz="0" iyy="{inertia}" iyz="0" izz="{inertia}"/>'
                '</inertial></link>\n')

    def joint(name: str, parent: str, child: str, xyz: str, axis: str, effort: float) -> str:
        return (f'  <joint name="{name}" type="revolute"><parent link="{parent}"/><child link="{child}"/>'
                f'<origin xyz="{xyz}" rpy="0 0 0"/><axis xyz="{axis}"/>'
                f'<limit lower="-3.0" upper="3.0" effort="{effort}" velocity="3.0"/>'
                '<dynamics damping="0.1" friction="0"/></joint>\n')

    urdf = ('<?xml version="1.0"?>\n<robot name="arm4">\n  <link name="base_link"/>\n'
            + joint("yaw", "base_link", "l1", "0 0 0", "0 0 1", EFFORT[0]) + link("l1", 3.0, "0 0 0.15", 0.02)
            + joint("shoulder", "l1", "l2", "0 0 0.3", "0 -1 0", EFFORT[1]) + link("l2", 2.0, "0.2 0 0", 0.03)
            + joint("elbow", "l2", "l3", "0.4 0 0", "0 -1 0", EFFORT[2]) + link("l3", 1.5, "0.175 0 0", 0.015)
            + joint("wrist", "l3", "l4", "0.35 0 0", "0 -1 0", EFFORT[3]) + link("l4", 0.5, "0.05 0 0", 0.001)
            + '  <joint name="tool_joint" type="fixed"><parent link="l4"/><child link="tool0"/>'
            '<origin xyz="0.1 0 0" rpy="0 0 0"/></joint>\n  <link name="tool0"/>\n</robot>\n')
    path = directory / "arm4.urdf"
    path.write_text(urdf)
    options = {"armature": [0.05, 0.05, 0.02, 0.01], "ee_frame": "tool0", "home": [0.0, 0.6, -1.2, 0.4],
               "contour_size": 0.1, "control_rate": 1000.0, "sample_rate": 500.0, "contour_bound": 1.0e-3}
    (directory / "arm4.yaml").write_text(yaml.safe_dump(options))
    return path


def pdsmc(env: dict, *args: str, timeout: float = 600) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "pdsmc_ros.cli", *args], env=env, capture_output=True, text=True,
                          timeout=timeout)


@pytest.mark.timeout(1200)
def test_a_new_arm_tuned_checked_and_run_in_real_time_over_dds(ros_env: dict, tmp_path: Path) -> None:
    arm = write_arm(tmp_path)
    params = tmp_path / "arm4_pdsmc.yaml"
    run = ["--robot", str(arm), "--contour", "circle", "--controller", "pdsmc"]
    tuned = pdsmc(ros_env, "tune", *run, "--rounds", "1", "--quiet", "--out", str(params))
    assert tuned.returncode == 0, tuned.stderr
    checked = pdsmc(ros_env, "check-gains", *run, "--params-file", str(params))  # real time, margin x2
    assert checked.returncode == 0, checked.stdout + checked.stderr
    assert "holds in realtime (zero-order hold + 2 periods of delay)" in checked.stdout
    simulated = pdsmc(ros_env, "simulate", *run, "--params-file", str(params), "--json")
    assert simulated.returncode == 0, simulated.stderr
    in_process = json.loads(simulated.stdout)

    out = tmp_path / "arm4_rt"
    env = {**ros_env, "ROS_DOMAIN_ID": str(next_domain())}
    proc = subprocess.Popen(["bash", str(ROOT / "scripts" / "run_experiment.sh"), *run, "--mode", "realtime",
                             "--params-file", str(params), "--out", str(out), "--timeout", "500"],
                            env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True)
    try:
        _, stderr = proc.communicate(timeout=560)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        _, stderr = proc.communicate()
        pytest.fail(f"run_experiment.sh timed out:\n{stderr}\n{node_log_tails(out)}")
    assert proc.returncode == 0, f"{stderr}\n{node_log_tails(out)}"
    analyzed = pdsmc(ros_env, "analyze", str(out), "--json")
    assert analyzed.returncode == 0, analyzed.stderr
    bag = json.loads(analyzed.stdout)[0]
    assert bag["complete"], bag["missing_steps"]
    assert np.all(np.asarray(bag["max_torque"]) <= np.asarray(EFFORT))  # within the arm's limits
    # tracks as the in-process run of the same gains does (a diverged loop is metres off, or NaN)
    assert bag["contour_mean"] <= 2.0 * in_process["contour_mean"] + 1e-3, (bag["contour_mean"], in_process)
