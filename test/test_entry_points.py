"""Every command works however it is started: clean environment, any directory (issue 13).

Each entry point runs as a subprocess from an empty temporary directory with
only ``HOME``, ``PATH=/usr/bin:/bin`` (and, for DDS, a ``ROS_DOMAIN_ID`` of the
test's own): no activated venv, no ``AMENT_PREFIX_PATH``, no ``NUMBA_CACHE_DIR``.
"""

from __future__ import annotations

import json
import os
import shlex
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from conftest import next_domain

from pdsmc_ros.errors import ConfigError, InvalidInputError
from pdsmc_ros.experiments.analysis import find_bags
from pdsmc_ros.resources import config_dir, data_root, ros_environment, script_path
from pdsmc_ros.runs.builder import MAX_CONTROL_STEPS, control_steps

BIN = Path(sys.prefix) / "bin"


def installed() -> None:
    if not (BIN / "pdsmc").exists() or not (Path(sys.prefix) / "lib" / "pdsmc_ros" / "plant").exists():
        pytest.skip("pdsmc_ros is not installed in this environment (run `make setup`)")


def clean_env(**extra: str) -> dict[str, str]:
    return {"HOME": os.environ.get("HOME", "/root"), "PATH": "/usr/bin:/bin", **extra}


def run(argv: list[str], cwd: Path, timeout: float = 300, **extra: str) -> subprocess.CompletedProcess:
    return subprocess.run(argv, cwd=cwd, env=clean_env(**extra), capture_output=True, text=True,
                          timeout=timeout)


def test_data_found_without_ros_environment(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("AMENT_PREFIX_PATH", raising=False)
    assert (config_dir() / "gains.yaml").is_file()
    assert script_path().is_file()
    assert (data_root() / "config" / "fastdds_profile.xml").is_file()


def test_ros_environment_adds_this_prefix_once() -> None:
    env = ros_environment({"PATH": "/usr/bin", "AMENT_PREFIX_PATH": "/opt/ros/jazzy"})
    assert env["AMENT_PREFIX_PATH"].split(os.pathsep) == [sys.prefix, "/opt/ros/jazzy"]
    assert ros_environment(env)["AMENT_PREFIX_PATH"] == env["AMENT_PREFIX_PATH"]
    assert env["PATH"].split(os.pathsep)[1:] == ["/usr/bin"]
    assert ros_environment({})["AMENT_PREFIX_PATH"] == sys.prefix


def test_run_size_is_bounded_before_allocation() -> None:
    assert control_steps(5.0, 10000.0) == 50000
    with pytest.raises(ConfigError, match="at most 10,000,000"):
        control_steps(5.0, 1e12)
    with pytest.raises(ConfigError, match="control steps"):
        control_steps(float("inf"), 1.0)
    assert control_steps(MAX_CONTROL_STEPS / 1000.0, 1000.0) == MAX_CONTROL_STEPS


def test_find_bags_expands_directories_and_skips_the_rest(tmp_path: Path) -> None:
    demo = tmp_path / "demo"
    for name in ("smc", "pd", "pdsmc"):
        (demo / name).mkdir(parents=True)
        (demo / name / f"{name}_0.mcap").write_bytes(b"")
        (demo / f"{name}.logs").mkdir()
    (demo / "notes.txt").write_text("x")
    bags, skipped = find_bags([demo])
    assert [b.name for b in bags] == ["pd", "pdsmc", "smc"]  # name order
    assert skipped == []
    # what a shell glob gives: bags, their log directories and a stray file
    bags, skipped = find_bags(sorted(demo.iterdir()))
    assert [b.name for b in bags] == ["pd", "pdsmc", "smc"]
    assert len(skipped) == 4 and all(line.startswith("skipping ") for line in skipped)
    assert any("pd.logs" in line and "no .mcap file" in line for line in skipped)
    with pytest.raises(InvalidInputError, match="does not exist"):
        find_bags([tmp_path / "nope"])


@pytest.mark.timeout(600)
def test_pdsmc_commands_in_a_clean_environment(tmp_path: Path) -> None:
    installed()
    sim = run([str(BIN / "pdsmc"), "simulate", "--robot", "parallel_5r", "--contour", "circle",
               "--controller", "pdsmc", "--json"], tmp_path)
    assert sim.returncode == 0, sim.stderr
    assert json.loads(sim.stdout)["contour_mean"] > 0
    chk = run([str(BIN / "pdsmc"), "check-gains", "--robot", "serial_3r", "--contour", "circle",
               "--controller", "pd", "--rate", "20000"], tmp_path)  # real time: x1.19 < x2, refused
    assert chk.returncode == 1 and "discrete-rate condition at 20000 Hz FAILS in realtime" in chk.stdout, chk.stderr
    chk = run([str(BIN / "pdsmc"), "check-gains", "--robot", "serial_3r", "--contour", "circle",
               "--controller", "pd", "--rate", "20000", "--mode", "lockstep"], tmp_path)
    assert chk.returncode == 0 and "discrete-rate condition at 20000 Hz holds in lockstep" in chk.stdout, chk.stderr
    swp = run([str(BIN / "pdsmc"), "sweep", "--param", "kp", "--robot", "parallel_5r", "--contour",
               "circle", "--values", "100", "--workers", "1"], tmp_path)
    assert swp.returncode == 0 and "kp varied" in swp.stdout, swp.stderr
    rep = run([str(BIN / "pdsmc"), "reproduce", "--only", "parallel_5r/circle/nominal/pd",
               "--out", "report", "--quiet"], tmp_path)
    assert rep.returncode == 0, rep.stderr
    assert (tmp_path / "report" / "REPRODUCTION.md").is_file()
    helps = [run([str(BIN / name), "--help"], tmp_path) for name in ("ros2", "pdsmc", "analyze")]
    assert all(h.returncode == 0 for h in helps), [h.stderr for h in helps]
    # numbers beyond what a run holds: one line, exit 2, nothing allocated
    long = tmp_path / "report" / "long.csv"  # one 1000 s segment: at 1 MHz, 1e9 steps
    long.write_text("x,y\n0.10,0.18\n0.11,0.18\n")
    for argv, needle in (
        (["simulate", "--robot", "serial_3r", "--contour", "circle", "--controller", "pd", "--rate", "1e12"],
         "--rate: expected a number in [0, 1e+06]"),  # the run table's bounds, as the nodes' rate parameter
        (["simulate", "--robot", "serial_3r", "--contour", "circle", "--controller", "pd", "--rate", "1e308"],
         "--rate: expected a number in [0, 1e+06]"),
        (["simulate", "--robot", "parallel_5r", "--contour", "csv", "--waypoints", "report/long.csv",
          "--segment-duration", "1000", "--controller", "pd", "--rate", "1000000"], "a run holds at most 10,000,000"),
        (["sweep", "--param", "kp", "--robot", "serial_3r", "--contour", "zigzag", "--workers", "100000"],
         "at most 256 processes"),
        (["analyze", "no_such_bag"], "does not exist"),
        # tune checks where it writes before its search, not after it
        (["tune", "--robot", "parallel_5r", "--contour", "circle", "--controller", "pd", "--out", "report"],
         "--out 'report' is a directory"),
        (["tune", "--robot", "parallel_5r", "--contour", "circle", "--controller", "pd", "--out",
          "report/REPRODUCTION.md/gains.yaml"], "cannot create 'report/REPRODUCTION.md'"),
    ):
        bad = run([str(BIN / "pdsmc"), *argv], tmp_path, timeout=60)
        assert bad.returncode == 2 and needle in bad.stderr, (argv, bad.stderr)
        assert len(bad.stderr.strip().splitlines()) == 1 and "Traceback" not in bad.stderr, bad.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["report"]


@pytest.mark.timeout(180)
def test_ros2_run_node_in_a_clean_environment(tmp_path: Path) -> None:
    installed()
    domain = str(next_domain())
    # SIGINT while running: a clean stop (the plant's once raised in the signal handler)
    for name, started in (("controller", "pdsmc controller for parallel_5r/circle"),
                          ("plant", "parallel_5r plant, lockstep")):
        proc = subprocess.Popen([str(BIN / "ros2"), "run", "pdsmc_ros", name, "--ros-args",
                                 "-p", "type:=pdsmc", "-p", "robot:=parallel_5r", "-p", "contour:=circle"],
                                cwd=tmp_path, env=clean_env(ROS_DOMAIN_ID=domain), stdout=subprocess.PIPE,
                                stderr=subprocess.STDOUT, text=True, start_new_session=True)
        try:
            deadline = time.monotonic() + 90
            seen = ""
            while time.monotonic() < deadline and started not in seen:
                line = proc.stdout.readline()  # type: ignore[union-attr]
                if not line:
                    break
                seen += line
            assert started in seen, seen
            os.killpg(proc.pid, signal.SIGINT)
            try:
                rest, _ = proc.communicate(timeout=20)
            except subprocess.TimeoutExpired:  # where it is stuck: its threads' stacks (SIGUSR1), then fail
                os.killpg(proc.pid, signal.SIGUSR1)
                time.sleep(2.0)
                os.killpg(proc.pid, signal.SIGKILL)
                stacks, _ = proc.communicate()
                raise AssertionError(f"{name} did not stop within 20 s of SIGINT:\n{seen}{stacks}") from None
        finally:
            if proc.poll() is None:
                os.killpg(proc.pid, signal.SIGKILL)
                proc.communicate()
        assert "Traceback" not in seen + rest, (name, seen + rest)
    unknown = run([str(BIN / "ros2"), "run", "pdsmc_ros", "nope"], tmp_path, timeout=60)
    assert unknown.returncode == 2 and "no executable 'nope'" in unknown.stderr, unknown.stderr
    # each node executable, started directly: it reads its parameters and refuses a bad one
    for name in ("plant", "trajectory", "controller", "recorder", "composed"):
        bad = run([str(BIN / name), "--ros-args", "-p", "robot:=nope"], tmp_path, timeout=60,
                  ROS_DOMAIN_ID=domain)
        assert bad.returncode == 2 and "unknown robot 'nope'" in bad.stderr, (name, bad.stderr)
        assert "Traceback" not in bad.stderr, (name, bad.stderr)


@pytest.mark.timeout(600)
def test_demo_hint_pasted_verbatim(tmp_path: Path) -> None:
    """A short demo from an empty directory, clean environment; its printed analyze command works."""
    installed()
    env = {"ROS_DOMAIN_ID": str(next_domain())}
    demo = run([str(BIN / "python"), "-m", "pdsmc_ros.cli.demo", "--duration-factor", "0.02",
                "--out", "demo"], tmp_path, timeout=540, **env)
    assert demo.returncode == 0, demo.stdout + demo.stderr
    hint = [line for line in demo.stdout.splitlines() if "analyse again with: " in line]
    assert len(hint) == 1, demo.stdout
    command = hint[0].split("analyse again with: ", 1)[1].rstrip(")")
    assert shlex.split(command)[1:] == ["analyze", "demo"]
    pasted = subprocess.run(["bash", "-c", command], cwd=tmp_path, env=clean_env(**env),
                            capture_output=True, text=True, timeout=120)
    assert pasted.returncode == 0, pasted.stderr
    assert all(label in pasted.stdout for label in ("PD (pd)", "SMC (smc)", "PD-SMC (pdsmc)")), pasted.stdout
    # the old hint, a shell glob over the runs and their logs: the logs are skipped, one line each
    globbed = subprocess.run(["bash", "-c", command.replace(" demo", " demo/*")], cwd=tmp_path,
                             env=clean_env(**env), capture_output=True, text=True, timeout=120)
    assert globbed.returncode == 0, globbed.stderr
    assert globbed.stdout == pasted.stdout
    # the glob adds the skipped logs and nothing else; what the run itself reports (a safe-mode
    # stretch on a loaded machine, say) is the same both ways
    skipped = [
        f"pdsmc analyze: skipping 'demo/{name}.logs': a directory with no .mcap file and no bag inside"
        for name in ("pd", "pdsmc", "smc")
    ]
    lines = globbed.stderr.strip().splitlines()
    assert sorted(line for line in lines if line in skipped) == skipped, globbed.stderr
    assert [line for line in lines if line not in skipped] == pasted.stderr.strip().splitlines(), globbed.stderr
    # the thesis-style comparison figures of the three runs (make figures does this at full length)
    figures = subprocess.run(["bash", "-c", command + " --plots --out figures"], cwd=tmp_path,
                             env=clean_env(**env), capture_output=True, text=True, timeout=300)
    assert figures.returncode == 0, figures.stderr
    for name in ("contour_error", "axial_torque", "contours"):
        png = tmp_path / "figures" / f"serial_3r_circle_{name}.png"
        assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n", name
