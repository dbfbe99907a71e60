"""Faults and bad input: dead nodes, killed recorder, rogue publishers, fuzzed validation."""

from __future__ import annotations

import dataclasses
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from conftest import next_domain, node_log_tails
from hypothesis import given, settings
from hypothesis import strategies as st

from pdsmc_ros.bag.mcapscan import scan
from pdsmc_ros.bag.reader import read_run
from pdsmc_ros.control import ControlLaw, Gains
from pdsmc_ros.control.soft_limits import effort_only_table, soft_limit
from pdsmc_ros.errors import InvalidInputError
from pdsmc_ros.sim import PlantStepper, simulate
from pdsmc_ros.sim.divergence import DivergenceCheck
from pdsmc_ros.sim.safe_mode import SafetyConfig, check_effort, safe_torque

ROOT = Path(__file__).resolve().parent.parent
SCRIPT = ROOT / "scripts" / "run_experiment.sh"


# --------------------------------------------------------------------------- #
# Core validation, fuzzed
# --------------------------------------------------------------------------- #
floats = st.floats(allow_nan=True, allow_infinity=True, width=64)


@settings(max_examples=300, deadline=None)
@given(st.lists(floats, min_size=0, max_size=6), st.sampled_from([list, tuple]))
def test_effort_validation_accepts_only_finite_right_length(data, container) -> None:  # noqa: ANN001
    # a tuple of floats is what the decoder gives the plant (its fast path)
    tau, reason = check_effort(container(data), 3)
    ok = len(data) == 3 and all(np.isfinite(data))
    assert (tau is not None) == ok
    if ok:
        assert reason == "" and np.array_equal(tau, np.asarray(data))
    else:
        assert reason and tau is None


@settings(max_examples=200, deadline=None)
@given(st.dictionaries(st.sampled_from(["kp", "kd", "ks", "lam", "phi", "kq"]),
                       st.one_of(st.lists(floats, max_size=4), floats, st.text(max_size=3)), max_size=5))
def test_gain_validation_never_crashes(data) -> None:  # noqa: ANN001
    try:
        gains = Gains.from_mapping(data, 3, "pdsmc")
    except InvalidInputError as exc:
        assert str(exc)  # a message naming what is wrong
    else:
        m = gains.matrix()
        assert m.shape == (5, 3) and np.all(np.isfinite(m)) and np.all(m >= 0) and np.all(m[4] > 0)


@settings(max_examples=100, deadline=None)
@given(st.sampled_from(["damp", "hold", "stop", ""]), floats, floats, st.sampled_from(["resume", "end", "x"]))
def test_safety_config_validation(mode, damping, stiffness, on_loss) -> None:  # noqa: ANN001
    try:
        cfg = SafetyConfig(mode=mode, damping=damping, stiffness=stiffness, on_loss=on_loss)
    except InvalidInputError as exc:
        assert "must be" in str(exc)
    else:
        q = np.array([0.1, -0.2])
        tau = safe_torque(cfg, q, np.array([1.0, -1.0]), np.zeros(2))
        assert np.all(np.isfinite(tau))
        # braking opposes the motion in both modes at the hold point
        at_hold = safe_torque(cfg, np.zeros(2), np.array([1.0, -1.0]), np.zeros(2))
        assert at_hold[0] <= 0.0 <= at_hold[1]


def test_torque_limit() -> None:
    counts = np.zeros(2, dtype=np.int64)
    tau = np.array([3.0, -9.0])
    assert soft_limit(tau, np.zeros(2), np.zeros(2), effort_only_table(np.array([5.0, 5.0]), 2), counts, 1) == 1
    assert tau.tolist() == [3.0, -5.0] and counts.tolist() == [0, 1]  # joint 2 at its limit
    tau = np.array([1.0])
    assert soft_limit(tau, np.zeros(1), np.zeros(1), effort_only_table(None, 1), counts, 1) == 0 and tau[0] == 1.0


# --------------------------------------------------------------------------- #
# Divergence caught (issue 29 item 3)
# --------------------------------------------------------------------------- #
def check_of_two() -> DivergenceCheck:
    return DivergenceCheck(("a", "b"), np.array([[-1.0, 1.0], [-np.inf, np.inf]]), np.array([2.0, np.inf]))


def test_divergence_check_bounds_come_from_the_limits() -> None:
    check = check_of_two()
    calm = np.zeros(2)
    assert check.check(calm, calm, 0) == -1
    assert check.check(np.array([1.5, 0.0]), calm, 3) == -2  # beyond a limit: a warning, once
    assert check.check(np.array([1.5, 0.0]), calm, 4) == -1
    assert check.new_warnings(1000.0) == [("joint 'a' position 1.5 rad beyond its limits [-1, 1] at t = 0.003 s "
                                           "(warned once per joint and run)")]
    assert check.new_warnings(1000.0) == []
    assert check.check(np.array([1.0 + 2 * np.pi + 0.1, 0.0]), calm, 5) == 0  # a turn past the stop
    assert check.check(calm, np.array([19.0, 0.0]), 6) == -2  # 9.5 x its velocity limit: a warning
    assert check.check(calm, np.array([21.0, 0.0]), 7) == 0  # 10.5 x: runaway
    assert check.check(calm, np.array([0.0, 999.0]), 8) == -1  # no velocity limit: 1000 rad/s
    assert check.check(calm, np.array([0.0, 1001.0]), 9) == 1
    assert check.check(np.array([0.0, np.nan]), calm, 10) == 1
    assert check.diverged(1, np.array([0.0, np.nan]), calm, 0.01) == (
        "diverged at t = 0.01 s: joint 'b' state is not finite (position nan, rate 0)")
    assert "rate 21 rad/s is beyond 10 x its velocity limit 2 rad/s" in check.diverged(
        0, calm, np.array([21.0, 0.0]), 0.0)


def test_a_recorded_runaway_torque_or_state_is_found() -> None:
    check = check_of_two()
    rows = np.zeros((5, 2))
    limit = np.array([10.0, np.inf])
    assert check.recorded(rows, rows, rows, limit, 100.0) == ""
    missing = rows.copy()
    missing[2] = np.nan  # a step not recorded is not a divergence
    assert check.recorded(missing, missing, missing, limit, 100.0) == ""
    tau = rows.copy()
    tau[3, 0] = 1.0e6
    assert check.recorded(rows, rows, tau, limit, 100.0) == (
        "diverged at t = 0.03 s: joint 'a' torque 1e+06 N m is beyond 100 x its effort limit 10 N m")
    qd = rows.copy()
    qd[1, 1] = np.inf
    assert check.recorded(rows, qd, tau, limit, 100.0).startswith("diverged at t = 0.01 s: joint 'b' state is not")


def unstable_serial_run():  # noqa: ANN201
    """The serial arm's PD with gains x300 at 1 kHz: far past the stability check (opted out)."""
    from pdsmc_ros.runs.builder import make_run

    spec = make_run("serial_3r", "circle", "pd", rate=1000.0)
    return dataclasses.replace(spec, gains=spec.gains.scaled({"kp": 300.0, "kd": 300.0}))


def test_the_in_process_simulator_stops_a_diverged_run() -> None:
    spec = unstable_serial_run()
    free = simulate(dataclasses.replace(spec, enforce_limits=False), check_stability=False)
    assert free.diverged.startswith("diverged at t = ") and "joint 'joint" in free.diverged
    assert np.isnan(free.metrics.contour_mean)  # stopped: the samples from then on are NaN
    stop = int(np.argmax(np.isnan(free.samples.q[:, 0])))
    assert 0 < stop < 10 and np.all(np.isnan(free.samples.q[stop:]))
    assert np.all(np.isfinite(free.samples.q[:stop]))
    # with the clamp the same gains chatter at the limits but stay bounded
    clamped = simulate(spec, check_stability=False)
    assert not clamped.diverged and min(clamped.metrics.saturated_periods) > 1000


def test_pdsmc_simulate_exits_1_in_one_line_when_the_run_diverges(monkeypatch: pytest.MonkeyPatch,
                                                                   capsys: pytest.CaptureFixture[str]) -> None:
    from pdsmc_ros import cli
    from pdsmc_ros.cli import simulate as simulate_command
    from pdsmc_ros.sim import simulator

    spec = unstable_serial_run()
    monkeypatch.setattr(simulate_command, "spec_from_args", lambda _args: spec)  # the gains injected
    monkeypatch.setattr(simulator, "check_rate", lambda *_a, **_k: None)  # past the stability check
    code = cli.main(["simulate", "--robot", "serial_3r", "--contour", "circle", "--controller", "pd",
                     "--no-enforce-limits"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 1
    assert [line for line in err if "error" in line] == [err[-1]]
    assert err[-1].startswith("pdsmc simulate: error: the run diverged at t = ") and err[-1].endswith("stopped there")


# --------------------------------------------------------------------------- #
# Faults through the orchestration
# --------------------------------------------------------------------------- #


def run_env(ros_env: dict, out: Path) -> dict:
    """An environment of its own DDS domain (shared by every process of this test run)."""
    return dict(ros_env, PDSMC_TEST_RUN=str(out), ROS_DOMAIN_ID=str(next_domain()),
                FASTRTPS_DEFAULT_PROFILES_FILE=str(ROOT / "config" / "fastdds_profile.xml"))


def start_experiment(env: dict, out: Path, *args: str) -> subprocess.Popen:
    return subprocess.Popen(
        ["bash", str(SCRIPT), "--robot", "serial_3r", "--contour", "circle", "--controller", "pdsmc",
         "--out", str(out), "--timeout", "200", *args],
        env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True,
    )


def wait_finish(proc: subprocess.Popen, timeout: float = 240) -> tuple[str, str]:
    """Wait for the orchestration; on failure its stderr carries the node logs' tails."""
    try:
        out, err = proc.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        out, err = proc.communicate()
        pytest.fail(f"orchestration timed out: {err}\n{bag_logs(proc)}")
    if proc.returncode != 0:
        err += "\n" + bag_logs(proc)
    return out, err


def bag_logs(proc: subprocess.Popen) -> str:
    """The node logs of the run ``proc`` orchestrates (found from its ``--out`` argument)."""
    args = list(proc.args)
    return node_log_tails(Path(args[args.index("--out") + 1])) if "--out" in args else ""


def node_pid(out: Path, name: str, timeout: float = 60) -> int:
    """PID of a node started by this test's orchestration (matched by its bag path)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        found = subprocess.run(["pgrep", "-f", f"lib/pdsmc_ros/{name} .*"], capture_output=True, text=True)
        for pid in found.stdout.split():
            try:
                cmdline = Path(f"/proc/{pid}/cmdline").read_bytes().decode(errors="replace")
                environ = Path(f"/proc/{pid}/environ").read_bytes().decode(errors="replace")
            except OSError:
                continue
            if str(out) in cmdline or f"PDSMC_TEST_RUN={out}" in environ:
                return int(pid)
        time.sleep(0.2)
    pytest.fail(f"node {name} of {out} not found")


def wait_steps(out: Path, steps: int, timeout: float = 120) -> None:
    """Wait until the recorder log says the run is going (the bag grows)."""
    deadline = time.monotonic() + timeout
    mcap = out / f"{out.name}.mcap"
    while time.monotonic() < deadline:
        if mcap.exists() and mcap.stat().st_size > steps * 300:
            return
        time.sleep(0.2)
    pytest.fail("the run did not start")


@pytest.mark.timeout(300)
def test_killed_controller_puts_plant_in_safe_mode_and_run_fails_clearly(ros_env: dict, tmp_path: Path) -> None:
    out = tmp_path / "killctl"
    env = run_env(ros_env, out)
    proc = start_experiment(env, out, "--duration-factor", "0.4", "--param", "watchdog_timeout:=0.5")
    wait_steps(out, 3000)
    os.kill(node_pid(out, "controller"), signal.SIGKILL)
    _, err = wait_finish(proc)
    assert proc.returncode != 0
    assert "node 'controller' failed (exit 137)" in err or "node 'controller' failed (exit -9)" in err
    run = read_run(out)  # closed cleanly by the orchestration (recorder last)
    assert not run.truncated
    diag = scan(out / f"{out.name}.mcap", ["/diagnostics"]).messages["/diagnostics"]
    assert any(b"controller lost" in m and b"safe mode 'damp'" in m for m in diag)


@pytest.mark.timeout(300)
def test_respawned_controller_resumes_the_run(ros_env: dict, tmp_path: Path) -> None:
    out = tmp_path / "respawn"
    env = run_env(ros_env, out)
    # safe mode advances sim time at 0.05 x wall clock (the rest of the motion lasts over 30 s),
    # so the respawned controller (about 4 s to start) finds the motion still running; at
    # 0.1 x (17 s) it once did not answer in time, on a loaded machine
    proc = start_experiment(env, out, "--duration-factor", "0.4", "--respawn", "controller",
                            "--param", "watchdog_timeout:=0.5", "--param", "safe_time_scale:=0.05")
    wait_steps(out, 3000)
    os.kill(node_pid(out, "controller"), signal.SIGKILL)
    _, err = wait_finish(proc)
    assert proc.returncode == 0, err
    assert "node 'controller' died (exit 137); respawning" in err
    plant_log = (Path(f"{out}.logs") / "plant.log").read_text()
    assert "controller lost" in plant_log and "safe mode off" in plant_log
    diag = scan(out / f"{out.name}.mcap", ["/diagnostics"]).messages["/diagnostics"]
    assert any(b"controller lost" in m for m in diag) and any(b"safe mode off" in m for m in diag)

    run = read_run(out)
    assert run.complete, run.missing
    assert run.plant_torque_steps > 100  # the safe-mode stretch, with the torque applied
    # before the kill: exactly the in-process run
    sim = simulate(run.spec)
    every = run.spec.sample_every
    law = ControlLaw.from_spec(run.spec)
    ref = run.spec.reference().sample(np.arange(run.steps + 1) / run.spec.rate)
    # the law's torque within the arm's effort limits: the way back after the safe stretch asks for
    # kilonewton-metres (the clamp, on by default, holds it at the arm's effort limits)
    limit = run.spec.robot_model().effort_limits
    commanded = np.array([np.array_equal(run.tau[k], np.clip(law.torque(run.q[k], run.qd[k], ref.q[k], ref.qd[k],
                                                                        ref.qdd[k]), -limit, limit))
                          for k in range(run.steps)])
    first_safe = int(np.argmin(commanded))
    resumed = first_safe + int(np.argmax(commanded[first_safe:]))
    assert 0 < first_safe < resumed < run.steps
    assert commanded[:first_safe].all() and commanded[resumed:].all()  # the law, bit for bit
    # the safe stretch, plus at most the last command of the killed controller, which
    # reached the plant but not the recorder
    assert resumed - first_safe <= run.plant_torque_steps <= resumed - first_safe + 1
    k_sim = np.arange(0, first_safe, every)
    assert np.max(np.abs(run.q[k_sim] - sim.samples.q[: len(k_sim)])) <= 1e-9
    analyzed = subprocess.run([sys.executable, "-m", "pdsmc_ros.cli", "analyze", str(out)],
                              capture_output=True, text=True, timeout=120)
    assert analyzed.returncode == 0, analyzed.stderr
    assert f"for {run.plant_torque_steps} steps the plant applied a torque other than a recorded command" \
        in analyzed.stderr
    # after the resume, every step is the plant's integration of the commanded torque
    stepper = PlantStepper(run.spec.robot_model(), 1.0 / run.spec.rate, run.q[resumed], run.qd[resumed])
    for k in range(resumed, run.steps):
        stepper.step(run.tau[k])
        assert np.array_equal(stepper.q, run.q[k + 1]) and np.array_equal(stepper.qd, run.qd[k + 1]), k
        stepper.q, stepper.qd = run.q[k + 1].copy(), run.qd[k + 1].copy()


@pytest.mark.timeout(300)
def test_killed_recorder_loses_at_most_a_second(ros_env: dict, tmp_path: Path) -> None:
    out = tmp_path / "killrec"
    env = run_env(ros_env, out)
    proc = start_experiment(env, out, "--duration-factor", "0.4")
    wait_steps(out, 6000)
    pid = node_pid(out, "recorder")
    os.kill(pid, signal.SIGKILL)
    killed_at = time.time_ns()
    wait_finish(proc)
    assert proc.returncode != 0
    run = read_run(out)
    assert run.truncated and not (out / "metadata.yaml").exists()
    recovered = scan(out / f"{out.name}.mcap", ["/joint_states"])
    last_logged = max(recovered.log_times["/joint_states"])
    lost_s = (killed_at - last_logged) * 1e-9
    assert 0.0 <= lost_s <= 1.0, lost_s
    assert run.counts["/joint_states"] > 1000
    # what was recovered is exactly the in-process run
    every = run.spec.sample_every
    sim = simulate(run.spec)
    seen = ~np.isnan(run.q[::every, 0])
    assert np.max(np.abs(run.q[::every][seen] - sim.samples.q[seen])) <= 1e-9


def wait_log(out: Path, name: str, line: str, timeout: float = 120) -> None:
    """Wait until node ``name``'s log in the orchestrated run ``out`` holds ``line``."""
    log = Path(f"{out}.logs") / f"{name}.log"
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if log.exists() and line in log.read_text(errors="replace"):
            return
        time.sleep(0.005)
    pytest.fail(f"{name} never logged {line!r}\n{node_log_tails(out)}")


@pytest.mark.timeout(300)
def test_recorder_killed_at_the_first_state_leaves_a_bag_that_names_its_run(ros_env: dict, tmp_path: Path) -> None:
    """Killed 50 ms after its first state reached it, long before the 0.5 s periodic flush.

    The kill is timed from the recorder's own report, not from the state's appearance on the
    wire: on a loaded machine a recorder may take longer than that to be scheduled, and an
    extra subscriber would count toward the subscribers the plant waits for.
    """
    out = tmp_path / "killfirst"
    env = run_env(ros_env, out)
    proc = start_experiment(env, out, "--duration-factor", "0.4")
    recorder = node_pid(out, "recorder")
    wait_log(out, "recorder", "first message on /joint_states")
    time.sleep(0.05)
    os.kill(recorder, signal.SIGKILL)
    wait_finish(proc)
    run = read_run(out)  # the run description reached the disk as it arrived
    assert run.truncated and run.description["controller"] == "pdsmc"
    assert run.counts["/joint_states"] >= 1  # so did the first states
    analyzed = subprocess.run([sys.executable, "-m", "pdsmc_ros.cli", "analyze", str(out)], env=env,
                              capture_output=True, text=True, timeout=120)
    assert "not a pdsmc_ros run" not in analyzed.stderr and "Traceback" not in analyzed.stderr
    if analyzed.returncode == 1 and "truncated" in analyzed.stderr and "PD-SMC (killfirst)" in analyzed.stdout:
        return  # enough complete steps reached the disk to compute statistics
    # killed before any step was complete: one line naming the run, no statistics
    assert analyzed.returncode == 1, analyzed.stderr
    assert analyzed.stderr.strip().splitlines() == [
        f"pdsmc analyze: error: bag {str(out)!r} (serial_3r/circle/pdsmc run, truncated) holds no control "
        "step with its state, reference and torque: nothing to analyse (recorded: "
        + ", ".join(f"{topic} {count}" for topic, count in run.counts.items()) + ")"
    ]


ROGUE = r"""
import sys, time, math
import rclpy
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy, HistoryPolicy
from std_msgs.msg import Float64MultiArray
rclpy.init()
node = Node("rogue")
pub = node.create_publisher(Float64MultiArray, "effort_controller/commands",
                            QoSProfile(reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_ALL))
bad = [[1.0, 2.0], [math.nan, 0.0, 0.0], [math.inf, 1.0, 1.0], [1.0, 2.0, 3.0, 4.0], [5.0, 5.0, 5.0]]
end = time.monotonic() + float(sys.argv[1])
i = 0
while time.monotonic() < end:
    msg = Float64MultiArray(data=bad[i % len(bad)])
    msg.layout.data_offset = 10**6 + i  # never the current step
    pub.publish(msg)
    i += 1
    rclpy.spin_once(node, timeout_sec=0.002)
print(i)
"""


@pytest.mark.timeout(300)
def test_rogue_efforts_are_rejected_and_the_run_is_unchanged(ros_env: dict, tmp_path: Path) -> None:
    out = tmp_path / "rogue"
    env = run_env(ros_env, out)
    # the rogue joins the run's DDS domain (run_env's)
    rogue = subprocess.Popen([sys.executable, "-c", ROGUE, "25"], env=env, stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE, text=True, start_new_session=True)
    proc = start_experiment(env, out, "--duration-factor", "0.1")
    _, err = wait_finish(proc)
    sent = rogue.communicate(timeout=60)[0]
    assert proc.returncode == 0, err
    assert int(sent.strip() or 0) > 100
    log = (Path(f"{out}.logs") / "plant.log").read_text()
    assert "rejected effort command" in log
    run = read_run(out)
    sim = simulate(run.spec)
    assert run.complete
    assert np.max(np.abs(run.q[:: run.spec.sample_every] - sim.samples.q)) <= 1e-9


@pytest.mark.timeout(300)
def test_two_lockstep_runs_give_identical_payloads(ros_env: dict, tmp_path: Path) -> None:
    payloads = []
    for name in ("a", "b"):
        out = tmp_path / name
        proc = start_experiment(ros_env, out, "--duration-factor", "0.04")
        _, err = wait_finish(proc)
        assert proc.returncode == 0, err
        topics = ["/joint_states", "/reference", "/effort_controller/commands"]
        payloads.append(scan(out / f"{out.name}.mcap", topics).messages)
    for topic in payloads[0]:
        assert payloads[0][topic] == payloads[1][topic], topic


FAKE_PLANT = r"""
import time
import rclpy
from rclpy.node import Node
from sensor_msgs.msg import JointState
rclpy.init()
node = Node("fake_plant")
pub = node.create_publisher(JointState, "joint_states", 10)
deadline = time.monotonic() + 60
while pub.get_subscription_count() < 1 and time.monotonic() < deadline:
    rclpy.spin_once(node, timeout_sec=0.05)
msg = JointState(name=["q1", "q2"], position=[0.0, 0.0], velocity=[0.0, 0.0], effort=[0.0, 0.0])
msg.header.stamp.nanosec = 40_000_000  # step 10 at 250 Hz
end = time.monotonic() + 1.5
while time.monotonic() < end:
    pub.publish(msg)
    rclpy.spin_once(node, timeout_sec=0.004)
node.destroy_node()
rclpy.shutdown()
"""


@pytest.mark.timeout(120)
def test_realtime_trajectory_ends_when_the_plant_leaves(ros_env: dict, tmp_path: Path) -> None:
    """The plant's last state may never arrive; its departure from the graph ends the node."""
    env = run_env(ros_env, tmp_path / "leave")
    log = tmp_path / "trajectory.log"
    with log.open("w") as sink:
        trajectory = subprocess.Popen(
            ["ros2", "run", "pdsmc_ros", "trajectory", "--ros-args", "-p", "mode:=realtime",
             "-p", "robot:=parallel_5r", "-p", "contour:=ellipse_vertical", "-p", "rate:=250.0",
             "-p", "sample_rate:=250.0", "-p", "duration_factor:=0.5"],
            env=env, stdout=sink, stderr=subprocess.STDOUT, start_new_session=True)
        plant = subprocess.Popen([sys.executable, "-c", FAKE_PLANT], env=env, start_new_session=True)
        try:
            assert plant.wait(timeout=90) == 0
            code = trajectory.wait(timeout=20)
        finally:
            for proc in (plant, trajectory):
                if proc.poll() is None:
                    os.killpg(proc.pid, signal.SIGKILL)
                    proc.wait()
    text = log.read_text()
    assert code == 0, text
    # no step is read from the stamps in real time: the node counts the states it received
    assert re.search(r"the plant has left \(\d+ states received\); stopping", text), text


def niceness(pid: int) -> int:
    """Niceness of a process (field 19 of /proc/PID/stat)."""
    stat = Path(f"/proc/{pid}/stat").read_text()
    return int(stat[stat.rindex(")") + 2 :].split()[16])


@pytest.mark.timeout(300)
def test_nice_applies_to_the_critical_path_only(ros_env: dict, tmp_path: Path) -> None:
    out = tmp_path / "nice"
    env = run_env(ros_env, out)
    proc = start_experiment(env, out, "--duration-factor", "0.2", "--nice", "5")
    try:
        seen = {name: niceness(node_pid(out, name)) for name in ("plant", "controller", "trajectory", "recorder")}
    finally:
        _, err = wait_finish(proc)
    assert proc.returncode == 0, err
    base = niceness(os.getpid())  # nice -n adds to the niceness the test runs at
    raised = min(base + 5, 19)
    assert seen == {"plant": raised, "controller": raised, "trajectory": base, "recorder": base}
    assert read_run(out).complete


TEARDOWN_HANG = r"""
import sys, time
from pdsmc_ros.loop.lifecycle import arm_teardown_watch
arm_teardown_watch(int(sys.argv[1]), seconds=0.3)
time.sleep(30)  # a teardown that never ends
"""


@pytest.mark.timeout(60)
@pytest.mark.parametrize("code", [0, 1])
def test_teardown_watch_ends_a_hung_exit_and_tells_done_from_failed(code: int) -> None:
    """After complete work a hang ends with SIGALRM (the orchestration's warning status);
    after a failure with status 1; both with the stack of where it hung."""
    proc = subprocess.run([sys.executable, "-c", TEARDOWN_HANG, str(code)], capture_output=True,
                          text=True, timeout=30)
    assert "Timeout (0:00:00" in proc.stderr and "time.sleep" not in proc.stdout
    assert "line 5" in proc.stderr  # where it hung
    assert proc.returncode == (-signal.SIGALRM if code == 0 else 1)


FAKE_ROS2 = """#!/usr/bin/env bash
# fake `ros2 run pdsmc_ros NAME ...`: FAKE_HANG names a node that ends like a hung teardown
# (SIGALRM), FAKE_FAIL one that fails; the others finish at once
[[ "$3" == "${FAKE_HANG:-}" ]] && kill -ALRM $$
[[ "$3" == "${FAKE_FAIL:-}" ]] && exit 1
exit 0
"""


@pytest.mark.timeout(60)
@pytest.mark.parametrize(("env_extra", "ok"), [({"FAKE_HANG": "trajectory"}, True),
                                               ({"FAKE_FAIL": "trajectory"}, False)])
def test_orchestration_warns_about_a_teardown_hang_but_fails_a_failure(
        tmp_path: Path, env_extra: dict, ok: bool) -> None:
    fake = tmp_path / "bin" / "ros2"
    fake.parent.mkdir()
    fake.write_text(FAKE_ROS2)
    fake.chmod(0o755)
    env = {**os.environ, "PATH": f"{fake.parent}:{os.environ['PATH']}", **env_extra}
    proc = subprocess.run(["bash", str(SCRIPT), "--robot", "serial_3r", "--contour", "circle", "--controller", "pd",
                           "--out", str(tmp_path / "bag")],
                          env=env, capture_output=True, text=True, timeout=30)
    if ok:
        assert proc.returncode == 0, proc.stderr
        assert "warning: node 'trajectory' finished its work, then hung in DDS teardown" in proc.stderr
    else:
        assert proc.returncode == 1
        assert "node 'trajectory' failed (exit 1)" in proc.stderr and "failed nodes: trajectory" in proc.stderr


PUSHER = r"""
import sys, time
import rclpy
from rclpy.node import Node
from std_msgs.msg import Float64MultiArray
rclpy.init()
node = Node("pusher")
pub = node.create_publisher(Float64MultiArray, "effort_controller/commands", 10)
end = time.monotonic() + float(sys.argv[1])
while time.monotonic() < end:
    pub.publish(Float64MultiArray(data=[1.0e5, -1.0e5]))  # far past any arm's limits
    rclpy.spin_once(node, timeout_sec=0.001)
"""

REALTIME_FIVE_BAR = ("--robot", "parallel_5r", "--contour", "ellipse_vertical", "--controller", "pd",
                     "--rate", "250", "--param", "sample_rate:=250.0",
                     "--param", "kp:=[40.0, 45.0]", "--param", "kd:=[3.0, 4.0]")


@pytest.mark.timeout(400)
def test_a_diverging_arm_fails_the_plant_the_script_and_is_marked_by_analyze(ros_env: dict, tmp_path: Path) -> None:
    """Torques far past the limits pushed into a real-time run with the clamp opted out: the plant
    stops with an error and exit 1, run_experiment.sh exits 1 saying so, analyze marks the bag."""
    out = tmp_path / "diverged"
    env = run_env(ros_env, out)
    # 80 s of contour: the divergence ends the run as soon as the pusher publishes (a loaded machine took
    # longer to start the pusher than a 16 s run lasted, and the run then ended well)
    proc = subprocess.Popen(["bash", str(SCRIPT), *REALTIME_FIVE_BAR, "--mode", "realtime", "--duration-factor", "20",
                             "--param", "enforce_limits:=false", "--out", str(out), "--timeout", "200"],
                            env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True)
    wait_steps(out, 20)  # the run is going: its bag will hold steps to analyse
    pusher = subprocess.Popen([sys.executable, "-c", PUSHER, "150"], env=env, stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE, text=True, start_new_session=True)
    try:
        _, err = wait_finish(proc)
    finally:
        pusher.kill()  # only the process this test started
        pusher.communicate(timeout=30)
    assert proc.returncode == 1, err
    assert "node 'plant' failed (exit 1)" in err
    assert re.search(r"run_experiment.sh: the run diverged at t = [0-9.e-]+ s: joint 'joint[12]'", err), err
    plant_log = (Path(f"{out}.logs") / "plant.log").read_text()
    assert "the plant stops (nothing more is integrated)" in plant_log
    # a run that went well, to compare with
    good = tmp_path / "good"
    proc = subprocess.Popen(["bash", str(SCRIPT), *REALTIME_FIVE_BAR, "--mode", "lockstep", "--duration-factor",
                             "0.5", "--out", str(good),
                             "--timeout", "200"], env=run_env(ros_env, good), stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, start_new_session=True)
    _, err = wait_finish(proc)
    assert proc.returncode == 0, err
    analysis = subprocess.run([sys.executable, "-m", "pdsmc_ros.cli", "analyze", str(good), str(out), "--plots",
                               "--out", str(tmp_path / "figures")], capture_output=True, text=True, timeout=300)
    assert analysis.returncode == 1
    assert f"pdsmc analyze: {out}: the run diverged at t = " in analysis.stderr
    assert "marked diverged, left out of the comparisons and of the comparison figures' scales" in analysis.stderr
    table = analysis.stdout
    assert "(diverged) DIVERGED" in table and "smaller mean contour error" not in table
    assert (tmp_path / "figures" / "contour_mean_comparison.png").is_file()

