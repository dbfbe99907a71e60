"""A law and a robot in a package of their own: built in a temporary directory, pip-installed,
run through ``pdsmc`` and the controller node (``ros2 run`` over DDS), uninstalled.

The package (:data:`PLUGIN_SOURCE`, the example of docs/how-to/plugins.md) declares a PID law
(gains ``kp``, ``kd`` shared with the thesis's laws and its own ``ki``, an integral state as the
``sta`` and ``ismc`` laws have, written in Python) and a planar two-link arm, as entry points of
``pdsmc_ros.laws`` and ``pdsmc_ros.robots``, and one broken entry point. Every run here is a
subprocess (the command line, the nodes), except the in-process reading of the bag; the package is
uninstalled and the test process's registries forget its law whatever happens.
"""

from __future__ import annotations

import importlib
import json
import os
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
import yaml
from conftest import node_log_tails

from pdsmc_ros.experiments.tuning import FACTORS

ROOT = Path(__file__).resolve().parent.parent
SCRIPT = ROOT / "scripts" / "run_experiment.sh"
DISTRIBUTION = "pdsmc-pid-example"
PIP = [sys.executable, "-m", "pip", "--disable-pip-version-check", "--no-input"]

PLUGIN_SOURCE = '''\
"""A PID law and a planar two-link arm for pdsmc_ros, in a package of their own."""

import numpy as np

from pdsmc_ros.control import GainSpec, LawEntry
from pdsmc_ros.robots import Manipulator, PlanarChain, RobotEntry
from pdsmc_ros.robots.base import diag

KI = GainSpec("ki", "integral gains Ki", "N m/(rad s)")


def pid_torque(setup, q, qd, q_ref, qd_ref, qdd_ref):
    """tau = Kp e + Kd edot + Ki z, z the integral of e (one float per joint of state)."""
    kp, kd, ki = setup.gains  # the rows of the law's gain matrix, in the order of its gains
    e = q_ref - q
    z = setup.state[0]  # a view: updated in place, once per control period h
    tau = kp * e + kd * (qd_ref - qd) + ki * z
    z += setup.h * e
    return tau


def pid_linear_gains(g, smc_model, mass):
    """Kp and Kd for the discrete stability check (the slow integral left out)."""
    return np.diag(g[0]), np.diag(g[1])


def pid_presets(source, model, q0):
    """Ki from the PD's presets: an integral time of 10 Kd / Kp."""
    return {"ki": source["kp"] ** 2 / (10.0 * source["kd"])}


PID = LawEntry("pid", "PID", ("kp", "kd", KI), pid_torque, "PID with an integral state",
               linear_gains=pid_linear_gains, state_size=1, presets_from="pd", derive_presets=pid_presets)


class Toy2R(Manipulator):
    """A planar 2R arm (x, y task point), numpy only."""

    name = "toy_2r"
    n = 2
    task_dim = 2
    joint_names = ("shoulder", "elbow")
    payload_link = 1

    def __init__(self, payload=0.0, *, params):
        super().__init__(payload, params=params)
        self.chain = PlanarChain(params.links, tip_mass=payload, gravity=params.gravity)

    def _fk(self, q):
        return self.chain.tip(q)

    def _ik(self, p):
        l1, l2 = self.chain.lengths
        c2 = (p[..., 0] ** 2 + p[..., 1] ** 2 - l1 * l1 - l2 * l2) / (2 * l1 * l2)
        q2 = np.arccos(np.clip(c2, -1.0, 1.0))
        q1 = np.arctan2(p[..., 1], p[..., 0]) - np.arctan2(l2 * np.sin(q2), l1 + l2 * np.cos(q2))
        return np.stack([q1, q2], axis=-1)

    def reachable(self, p):
        l1, l2 = self.chain.lengths
        d = np.hypot(p[..., 0], p[..., 1])
        return (d > abs(l1 - l2) + 1e-3) & (d < l1 + l2 - 1e-3)

    def _jacobian(self, q):
        return self.chain.tip_jacobian(q)

    def joint_rates(self, q, pd, pdd):
        jac = self._jacobian(q)
        qd = np.linalg.solve(jac, pd[..., None])[..., 0]
        jdot = self.chain.tip_jacobian_dot(q, qd)
        qdd = np.linalg.solve(jac, (pdd - np.einsum("...ij,...j->...i", jdot, qd))[..., None])[..., 0]
        return qd, qdd

    def _mass_matrix(self, q):
        return self.chain.mass_matrix(q) + diag(self.J)

    def _coriolis_matrix(self, q, qd):
        return self.chain.coriolis_matrix(q, qd)

    def _gravity(self, q):
        return self.chain.gravity_vector(q)

    def _potential(self, q):
        return self.chain.potential_energy(q)


TOY_2R = RobotEntry(Toy2R, config={
    "links": [{"mass": 1.2, "length": 0.4, "com": 0.2, "inertia": 0.02},
              {"mass": 0.8, "length": 0.3, "com": 0.15, "inertia": 0.01}],
    "motor_inertia": 0.02, "motor_damping": 0.05,
    "control_rate": 2000.0, "sample_rate": 500.0, "contour_bound": 1e-3,
})
'''

PYPROJECT = f'''\
[build-system]
requires = ["setuptools"]
build-backend = "setuptools.build_meta"

[project]
name = "{DISTRIBUTION}"
version = "0.1.0"
dependencies = ["pdsmc_ros"]

[tool.setuptools]
py-modules = ["pdsmc_pid_example"]

[project.entry-points."pdsmc_ros.laws"]
pid = "pdsmc_pid_example:PID"
broken = "pdsmc_pid_example:NO_SUCH_LAW"

[project.entry-points."pdsmc_ros.robots"]
toy_2r = "pdsmc_pid_example:TOY_2R"
'''

SQUARE = "x,y\n0.45,0.05\n0.45,0.15\n0.35,0.15\n0.35,0.05\n0.45,0.05\n"


def pip(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([*PIP, *args], capture_output=True, text=True, timeout=300)


def forget_plugin() -> None:
    """The test process's registries and import caches as before the package (later tests list the laws)."""
    from pdsmc_ros.control import unregister_law
    from pdsmc_ros.robots import unregister_robot

    unregister_law("pid")
    unregister_robot("toy_2r")
    sys.modules.pop("pdsmc_pid_example", None)
    importlib.invalidate_caches()


@pytest.fixture(scope="module")
def installed(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Path]:
    """The package built and installed into this environment; uninstalled after the module's tests."""
    source = tmp_path_factory.mktemp("pdsmc_pid_example")
    (source / "pyproject.toml").write_text(PYPROJECT)
    (source / "pdsmc_pid_example.py").write_text(PLUGIN_SOURCE)
    pip("uninstall", "-y", DISTRIBUTION)  # a copy left by a run that was killed
    try:
        proc = pip("install", "--no-deps", "--no-build-isolation", "--no-index", str(source))
        assert proc.returncode == 0, proc.stdout + proc.stderr
        importlib.invalidate_caches()
        yield source
    finally:
        done = pip("uninstall", "-y", DISTRIBUTION)
        forget_plugin()
        assert done.returncode == 0, done.stdout + done.stderr


def pdsmc(*args: str, timeout: float = 300) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "pdsmc_ros.cli", *args], cwd=ROOT, capture_output=True, text=True,
                          timeout=timeout)


def test_the_installed_law_and_robot_are_registered_after_the_built_ins(installed: Path) -> None:  # noqa: ARG001
    script = ("import json; from pdsmc_ros.control import law_names, gain_specs, law; "
              "from pdsmc_ros.robots import robot_names; "
              "print(json.dumps([law_names(), {k: g.help() for k, g in gain_specs().items()}, robot_names(), "
              "law('pid').gain_names, law('pid').state_size]))")
    proc = subprocess.run([sys.executable, "-c", script], cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    laws, gains, robots, pid_gains, state_size = json.loads(proc.stdout)
    # the broken one left out
    assert laws == ["pd", "smc", "pdsmc", "pdg", "ctc", "sta", "ismc", "pd_pos", "pdsmc_pos", "pid"]
    assert list(gains)[-1] == "ki" and gains["ki"].startswith("integral gains Ki (N m/(rad s), one per joint")
    assert robots == ["serial_3r", "parallel_5r", "toy_2r"]
    assert pid_gains == ["kp", "kd", "ki"] and state_size == 1
    # the broken entry point: one line naming the distribution and the entry point, the rest unharmed
    warning = [line for line in proc.stderr.splitlines() if "broken" in line]
    assert warning == [(f"plugin {DISTRIBUTION} 0.1.0: entry point pdsmc_ros.laws 'broken = pdsmc_pid_example:"
                       "NO_SUCH_LAW' does not load: AttributeError: module 'pdsmc_pid_example' has no attribute "
                       "'NO_SUCH_LAW' (left out)")], proc.stderr


@pytest.mark.timeout(900)
def test_pdsmc_simulate_runs_the_installed_law_with_its_gains_as_flags(installed: Path) -> None:  # noqa: ARG001
    proc = pdsmc("simulate", "--robot", "serial_3r", "--contour", "circle", "--controller", "pid", "--json")
    assert proc.returncode == 0, proc.stderr
    result = json.loads(proc.stdout)
    assert result["run"]["controller"] == "pid" and 0.0 < result["contour_mean"] < 1e-3, result
    assert "broken" not in proc.stderr  # a run of one law loads no other plugin
    bad = pdsmc("simulate", "--robot", "serial_3r", "--contour", "circle", "--controller", "pid", "--gain", "ki=-1")
    assert bad.returncode == 2 and "gain ki of pid must be finite and >= 0, got [-1.0, -1.0, -1.0]" in bad.stderr


@pytest.mark.timeout(900)
def test_check_gains_and_compare_take_the_installed_law(installed: Path) -> None:  # noqa: ARG001
    checked = pdsmc("check-gains", "--robot", "serial_3r", "--contour", "circle", "--controller", "pid", "--mode",
                    "lockstep")
    assert checked.returncode == 0 and "ki=" in checked.stdout, checked.stdout + checked.stderr
    compared = pdsmc("compare", "--robot", "serial_3r", "--contour", "circle", "--laws", "pd,pid",
                     "--json", timeout=600)
    assert compared.returncode == 0, compared.stderr
    assert [row["law"] for row in json.loads(compared.stdout)["rows"]] == ["pd", "pid"]


def test_a_broken_plugin_asked_for_is_one_line_and_the_built_ins_run(installed: Path) -> None:  # noqa: ARG001
    proc = pdsmc("simulate", "--robot", "serial_3r", "--contour", "circle", "--controller", "broken")
    assert proc.returncode == 2
    assert proc.stderr.splitlines() == [
        (f"pdsmc simulate: error: plugin {DISTRIBUTION} 0.1.0: entry point pdsmc_ros.laws 'broken = "
        "pdsmc_pid_example:NO_SUCH_LAW' does not load: AttributeError: module 'pdsmc_pid_example' has no "
        "attribute 'NO_SUCH_LAW'")]


def test_the_installed_robot_runs_the_installed_law(installed: Path, tmp_path: Path) -> None:  # noqa: ARG001
    square = tmp_path / "square.csv"
    square.write_text(SQUARE)
    proc = pdsmc("simulate", "--robot", "toy_2r", "--contour", "csv", "--waypoints", str(square),
                 "--segment-duration", "0.5", "--controller", "pid", "--gain", "kp=400,200", "--gain", "kd=40,20",
                 "--gain", "ki=800,400", "--json")
    assert proc.returncode == 0, proc.stderr
    result = json.loads(proc.stdout)
    assert result["run"]["robot"] == "toy_2r" and result["steps"] == 4000  # four 0.5 s segments at its 2 kHz
    assert 0.0 < result["contour_mean"] < 5e-3


@pytest.mark.timeout(1200)
def test_tune_then_the_controller_node_over_dds_equals_in_process(installed: Path, tmp_path: Path,  # noqa: ARG001
                                                                  ros_env: dict) -> None:
    """``pdsmc tune`` writes the law's gains, ``ki`` among them; the controller node (``ros2 run
    pdsmc_ros controller -p type:=pid``, started by scripts/run_experiment.sh) declares them as
    parameters, takes the file, and runs the step-for-step run of the simulator."""
    params = tmp_path / "pid.yaml"
    tuned = pdsmc("tune", "--robot", "serial_3r", "--contour", "circle", "--controller", "pid", "--rounds", "1",
                  "--rate", "2000", "--out", str(params), timeout=900)  # 2 kHz: a fifth of the serial arm's steps
    assert tuned.returncode == 0, tuned.stderr
    gains = yaml.safe_load(params.read_text())["controller"]["ros__parameters"]
    assert set(gains) >= {"kp", "kd", "ki"} and min(gains["ki"]) > 0.0, gains
    # ki is swept as kp and kd are (one line per candidate: "... kp=[...], kd=[...], ki=[...]")
    tried_ki = {line.split("ki=")[1] for line in tuned.stderr.splitlines() if "ki=" in line}
    assert len(tried_ki) >= 1 + len(FACTORS), tuned.stderr

    out = tmp_path / "pid"
    env = {**ros_env, "PYTHONPATH": os.pathsep.join(p for p in (str(ROOT), ros_env.get("PYTHONPATH", "")) if p)}
    proc = subprocess.run(["bash", str(SCRIPT), "--robot", "serial_3r", "--contour", "circle", "--controller", "pid",
                           "--duration-factor", "0.05", "--params-file", str(params), "--out", str(out),
                           "--timeout", "240"],
                          env=env, capture_output=True, text=True, timeout=300, start_new_session=True)
    assert proc.returncode == 0, proc.stderr + node_log_tails(out)
    controller_log = (Path(f"{out}.logs") / "controller.log").read_text()
    assert "unknown parameter" not in controller_log and "ignored" not in controller_log, controller_log

    from pdsmc_ros.bag.reader import read_run
    from pdsmc_ros.sim import simulate

    run = read_run(out)
    assert run.spec.controller == "pid" and run.spec.gains["ki"] == pytest.approx(gains["ki"], rel=0, abs=0)
    sim = simulate(run.spec)
    every = run.spec.sample_every
    assert run.spec.rate == 2000.0 and run.steps == 500  # 0.25 s at the params file's rate
    assert np.max(np.abs(run.q[::every] - sim.samples.q)) <= 1e-9
    assert np.max(np.abs(run.tau[::every] - sim.samples.tau)) <= 1e-9
