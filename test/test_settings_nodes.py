"""The nodes' settings: gains scaled by the scenario as in-process, gains needed by the controller only,
undeclared overrides warned about, bad params files refused, the controller's rate advice as a parameter."""

from __future__ import annotations

import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest
import yaml
from conftest import next_domain

from pdsmc_ros.errors import ConfigError
from pdsmc_ros.runs.builder import make_run, scenario_names

rclpy = pytest.importorskip("rclpy")
from rclpy.parameter import Parameter  # noqa: E402

from pdsmc_ros.control import Gains  # noqa: E402
from pdsmc_ros.parameters.ros import declare_run_parameters  # noqa: E402
from pdsmc_ros.ros.node_run import run_spec_from_parameters  # noqa: E402

GIVEN = {"kp": [300.0, 200.0], "kd": [20.0, 30.0], "ks": [1.5, 2.0], "lam": [10.0, 12.0], "phi": [0.4, 0.5]}


@pytest.fixture
def context() -> Iterator[object]:
    ctx = rclpy.context.Context()
    rclpy.init(context=ctx)
    try:
        yield ctx
    finally:
        rclpy.shutdown(context=ctx)


def node_spec(context: object, overrides: dict, *, needs_gains: bool = True):  # noqa: ANN201
    node = rclpy.create_node("controller", context=context,
                             parameter_overrides=[Parameter(k, value=v) for k, v in overrides.items()])
    try:
        declare_run_parameters(node, gains=needs_gains)
        return run_spec_from_parameters(node, needs_gains=needs_gains)
    finally:
        node.destroy_node()


@pytest.mark.parametrize("scenario", scenario_names())
def test_given_gains_are_scaled_by_the_scenario_as_in_process(context: object, scenario: str) -> None:
    run = {"robot": "parallel_5r", "contour": "circle", "type": "pdsmc", "scenario": scenario}
    spec = node_spec(context, {**run, **GIVEN})
    given = Gains.from_mapping(GIVEN, 2, "pdsmc")
    expected = make_run("parallel_5r", "circle", "pdsmc", scenario=scenario, gains=given)
    assert spec.gains == expected.gains  # pdsmc simulate --params-file builds exactly this
    partial = node_spec(context, {**run, "kp": GIVEN["kp"]})  # one gain given, the others the preset's
    preset = make_run("parallel_5r", "circle", "pdsmc").gains.as_dict()
    unscaled = make_run("parallel_5r", "circle", "pdsmc", gains=Gains.from_mapping({**preset, "kp": GIVEN["kp"]}, 2,
                                                                                  "pdsmc"), scenario=scenario)
    assert partial.gains == unscaled.gains
    if scenario == "high_pd":
        assert spec.gains["kp"] == (450.0, 300.0) and spec.gains["ks"] == tuple(GIVEN["ks"])


@pytest.mark.parametrize("scenario", scenario_names())
def test_a_params_file_and_overrides_give_the_same_gains_in_process_and_in_the_node(
        context: object, scenario: str, tmp_path: Path) -> None:
    """The one run builder's layers (presets, params file, explicit overrides, then the scenario) give the
    same gains to ``pdsmc simulate`` (--params-file, --gain) and to the controller node (--params-file, -p)."""
    from pdsmc_ros import cli
    from pdsmc_ros.control import law

    for controller in ("pd", "smc", "pdsmc"):
        path = tmp_path / f"{controller}.yaml"
        own = {k: v for k, v in GIVEN.items() if k in ("kp", "ks")}  # part of the law's gains: presets give the rest
        file_gains = {k: v for k, v in own.items() if k in make_run("parallel_5r", "circle", controller).gains}
        preset = make_run("parallel_5r", "circle", controller).gains
        path.write_text(yaml.safe_dump({"/**": {"ros__parameters": {"type": controller}},
                                        "controller": {"ros__parameters": file_gains}}))
        override = "kd" if controller != "smc" else "lam"
        args = cli.build_parser().parse_args(
            ["simulate", "--robot", "parallel_5r", "--contour", "circle", "--controller", controller, "--scenario",
             scenario, "--params-file", str(path), "--gain", f"{override}={GIVEN[override][0]},{GIVEN[override][1]}"])
        in_process = cli.spec_from_args(args)
        node = rclpy.create_node("controller", context=context, cli_args=[
            "--ros-args", "-p", "robot:=parallel_5r", "-p", "contour:=circle", "-p", f"scenario:={scenario}",
            "--params-file", str(path), "-p", f"{override}:={GIVEN[override]}"])
        try:
            declare_run_parameters(node, gains=True)
            in_node = run_spec_from_parameters(node)
        finally:
            node.destroy_node()
        assert in_node.controller == controller and in_node.gains == in_process.gains, (controller, scenario)
        factors = {"high_pd": {"kp": 1.5, "kd": 1.5}, "high_smc": {"ks": 1.5, "lam": 1.5}}.get(scenario, {})
        for name in in_node.gains:  # the layers in order, then the scenario's factors on the law's own gains
            given = GIVEN[name] if name in file_gains or name == override else preset[name]
            factor = factors.get(name, 1.0) if name in law(controller).gain_names else 1.0
            assert in_node.gains[name] == tuple(v * factor for v in given), (controller, scenario, name)


def test_only_the_controller_needs_gains(context: object) -> None:
    run = {"robot": "ur3", "contour": "circle", "type": "pdsmc"}  # no preset gains for the UR3
    plant = node_spec(context, run, needs_gains=False)
    assert plant.robot == "ur3" and len(plant.gains["kp"]) == 6
    with pytest.raises(ConfigError, match=r"pdsmc needs gains kp, kd, ks, lam, phi: this arm has no preset.*tune"):
        node_spec(context, run)
    gains = {k: [v[0]] * 6 for k, v in GIVEN.items()}
    assert node_spec(context, {**run, **gains}).gains == Gains.from_mapping(gains, 6, "pdsmc")


def ros2_run(ros_env: dict, node: str, *args: str, timeout: float = 120) -> subprocess.CompletedProcess:
    """Start ``node`` and stop it with SIGINT after ``timeout`` s if it has not ended (a node that
    starts runs on: its warnings are read from what it printed)."""
    env = {**ros_env, "ROS_DOMAIN_ID": str(next_domain())}
    return subprocess.run(["timeout", "-s", "INT", str(timeout), "ros2", "run", "pdsmc_ros", node, "--ros-args", *args],
                          env=env, capture_output=True, text=True, timeout=timeout + 30)


@pytest.mark.timeout(200)
def test_an_undeclared_override_is_warned_about_naming_the_closest(ros_env: dict) -> None:
    proc = ros2_run(ros_env, "trajectory", "-p", "robot:=parallel_5r", "-p", "typ:=pd", timeout=25)
    assert "unknown parameter 'typ' (did you mean 'type'?)" in proc.stderr, proc.stderr


@pytest.mark.timeout(200)
def test_an_undeclared_override_is_named_even_when_the_node_cannot_start(ros_env: dict) -> None:
    """-p typ:=pd left the default law (PD-SMC), whose thesis gains real time refuses: the user
    must hear of the typo too, not only of the gains."""
    proc = ros2_run(ros_env, "controller", "-p", "mode:=realtime", "-p", "typ:=pd", timeout=60)
    assert proc.returncode == 2, proc.stderr
    assert "controller: warning: unknown parameter 'typ' (did you mean 'type'?): ignored" in proc.stderr, proc.stderr


@pytest.mark.timeout(300)
@pytest.mark.parametrize(("content", "message"), [
    ({"trajectroy": {"ros__parameters": {"robot": "parallel_5r"}}},
     ("params file '{}': no section for node '/trajectory' or any node of the package (sections: 'trajectroy'; "
      "use 'trajectory:' or '/**:'")),
    ({"/**": {"ros__parameters": {"robot": "parallel_5r", "kpp": [1.0, 2.0]}}},
     "params file '{}': section '/**': unknown parameter 'kpp' (did you mean 'kp'?) for node '/trajectory'"),
])
def test_a_bad_params_file_is_one_line_and_exit_2(ros_env: dict, tmp_path: Path, content: dict, message: str) -> None:
    path = tmp_path / "params.yaml"
    path.write_text(yaml.safe_dump(content))
    proc = ros2_run(ros_env, "trajectory", "--params-file", str(path), timeout=60)
    assert proc.returncode == 2, proc.stderr
    errors = [line for line in proc.stderr.splitlines() if "error" in line]
    assert errors == [f"trajectory: error: {message.format(path)}" + errors[0].split(message.format(path))[1]]


@pytest.mark.timeout(300)
def test_the_controller_refuses_gains_unstable_in_real_time_advising_the_parameter(ros_env: dict) -> None:
    # the UR5's old shipped gains: x1.04 without delay, unstable with the real-time loop's delay
    old = {"kp": [179700.0, 514400.0, 136400.0, 38820.0, 40500.0, 2742.0],
           "kd": [28.08, 80.37, 21.31, 6.066, 6.329, 0.4284], "ks": [112.3, 321.5, 85.22, 24.26, 25.31, 1.714],
           "lam": [1600.0] * 6, "phi": [0.25] * 6}
    gains = [arg for k, v in old.items() for arg in ("-p", f"{k}:={v}")]
    proc = ros2_run(ros_env, "controller", "-p", "robot:=ur5", "-p", "mode:=realtime", *gains, timeout=120)
    assert proc.returncode == 2, proc.stderr
    errors = [line for line in proc.stderr.splitlines() if "error" in line]
    assert len(errors) == 1 and "realtime (zero-order hold + 2 periods of delay)" in errors[0], proc.stderr
    assert "-p rate:=" in errors[0] and "--rate" not in errors[0]


@pytest.mark.timeout(200)
def test_the_cli_knows_every_parameter_the_controller_declares(ros_env: dict) -> None:
    """The controller's table (settings.CONTROLLER_PARAMETERS and the laws' gains: what pdsmc --params-file
    accepts without ROS) is what the node declares."""
    from pdsmc_ros.parameters.params_file import ALWAYS_DECLARED, CONTROLLER_PARAMETERS

    env = {**ros_env, "ROS_DOMAIN_ID": str(next_domain())}
    script = ("import sys, rclpy\n"
              "from pdsmc_ros.controller.node import ControllerNode\n"
              "from pdsmc_ros.loop.realtime_params import declare_realtime_parameters\n"
              "rclpy.init(args=['--ros-args', '-p', 'robot:=parallel_5r', '-p', 'autostart:=false'])\n"
              "wrapper = ControllerNode()\n"
              "declare_realtime_parameters(wrapper.node, 'realtime')\n"
              "print(' '.join(wrapper.node.list_parameters([], 0).names))\n"
              "wrapper.action.stop()\n"  # the action server's thread ends before the context does
              "wrapper.node.destroy_node()\n"
              "rclpy.shutdown()\n")
    proc = subprocess.run([sys.executable, "-c", script], env=env, capture_output=True, text=True, timeout=150)
    assert proc.returncode == 0, proc.stderr
    declared = set(proc.stdout.split()) - set(ALWAYS_DECLARED)
    from pdsmc_ros.control import gain_names
    from pdsmc_ros.parameters import node_parameters

    table = node_parameters("controller")  # what settings.CONTROLLER_PARAMETERS is derived from
    assert {name for name in declared if not any(spec.matches(name) for spec in table)} == set()
    assert {spec.name for spec in table} == set(CONTROLLER_PARAMETERS) | set(gain_names())  # templates included
    assert {spec.name for spec in table if not spec.map_joints} <= declared
    assert {"constraints.joint1.goal", "constraints.joint2.trajectory"} <= declared  # one per joint
