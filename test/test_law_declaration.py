"""A law declares itself: one registered here, with a gain no other law has, runs through
``pdsmc simulate``, the controller node's parameters, ``pdsmc check-gains`` and ``pdsmc tune``.

The law is a PD with a scalar share ``kg`` of the nominal model's gravity compensated
(``tau = Kp e + Kd edot + kg G(q)``, not a thesis law): it has no state, so the loop needs none.
Its ``kg`` is one value for every joint, in [0, 1]; nothing else in the package names it. Without a
compiled form it runs behind control.python_form (a Python call a step): the runs here are the
serial zigzag at 500 Hz, with the gains of ``pdsmc tune``'s starting point for that rate.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
import yaml

from pdsmc_ros import cli
from pdsmc_ros.control import GAINS, GainSpec, LawEntry, LawSetup, gain_names, law, register_law, unregister_law
from pdsmc_ros.errors import ConfigError
from pdsmc_ros.robots.base import FloatArray
from pdsmc_ros.runs.builder import make_run
from pdsmc_ros.sim import simulate

KG = GainSpec("kg", "share of the nominal model's gravity compensated", "1", per_joint=False, upper=1.0, start=1.0)
RUN = ["--robot", "serial_3r", "--contour", "zigzag", "--controller", "pd_g", "--rate", "500"]


def pd_g_torque(setup: LawSetup, q: FloatArray, qd: FloatArray, q_ref: FloatArray, qd_ref: FloatArray,
                qdd_ref: FloatArray) -> FloatArray:  # noqa: ARG001
    """``Kp e + Kd edot + kg G(q)``: rows kp, kd, kg of its own gain matrix."""
    g = setup.gains
    return g[0] * (q_ref - q) + g[1] * (qd_ref - qd) + g[2] * setup.model.gravity(q)


def pd_g_linear(g: FloatArray, smc_model: FloatArray, mass: FloatArray) -> tuple[FloatArray, FloatArray]:  # noqa: ARG001
    """Its linear part: the PD's (gravity is no feedback of the error)."""
    return np.diag(g[0]), np.diag(g[1])


def pd_gains() -> dict[str, list[float]]:
    """Kp and Kd stable at 500 Hz (tune's starting point, :func:`pdsmc_ros.experiments.tuning.starting_gains`)."""
    from pdsmc_ros.experiments.tuning import starting_gains

    placeholder = {"kp": [1.0], "kd": [1.0], "kg": 1.0}
    start = starting_gains(make_run("serial_3r", "zigzag", "pd_g", rate=500.0, overrides=placeholder))
    return {"kp": list(start["kp"]), "kd": list(start["kd"])}


def flags(gains: dict[str, list[float]]) -> list[str]:
    return [arg for k, v in gains.items() for arg in ("--gain", f"{k}={','.join(map(repr, v))}")]


@pytest.fixture
def pd_g() -> Iterator[None]:
    register_law(LawEntry("pd_g", "PD+kg G", ("kp", "kd", KG), pd_g_torque, "a test's own law",
                          linear_gains=pd_g_linear))
    yield
    unregister_law("pd_g")
    assert "kg" not in gain_names()


def test_the_declaration_is_what_the_package_knows(pd_g: None) -> None:  # noqa: ARG001
    assert law("pd_g").gain_names == ("kp", "kd", "kg") and GAINS["kg"] is KG
    assert GAINS["kp"] is law("pd").specs[0]  # "kp" named by string: the declared spec, shared
    with pytest.raises(ValueError, match="declared otherwise"):
        register_law(LawEntry("other", "X", (GainSpec("kg", "another meaning", "N m"),), pd_g_torque))
    spec = make_run("parallel_5r", "circle", "pd_g", overrides={"kp": [230, 260], "kd": [24, 36], "kg": 0.5})
    assert spec.gains["kg"] == (0.5,) and spec.gains.matrix()[2].tolist() == [0.5, 0.5]
    high_pd = make_run("parallel_5r", "circle", "pd_g", scenario="high_pd",
                       overrides={"kp": [230, 260], "kd": [24, 36], "kg": 0.5})
    assert high_pd.gains["kp"] == (345.0, 390.0) and high_pd.gains["kg"] == (0.5,)  # kg: no scenario factor
    for bad, message in (({"kg": 1.5}, r"gain kg of pd_g must be finite and >= 0 and <= 1"),
                         ({"kg": [0.5, 0.5]}, r"gain kg needs one value \(for every joint\), got 2"),
                         ({"kg": 0.5, "ki": [1.0, 1.0]}, r"unknown gain\(s\) \['ki'\] for pd_g; allowed: kp, kd, kg")):
        with pytest.raises(ConfigError, match=message):
            make_run("parallel_5r", "circle", "pd_g", overrides={"kp": [230, 260], "kd": [24, 36], **bad})


def test_kg_reaches_the_law(pd_g: None) -> None:  # noqa: ARG001
    """kg = 0 is the thesis's PD (its compiled form) to 1e-9; kg = 1 holds the arm against gravity."""
    given = pd_gains()
    runs = {name: simulate(make_run("serial_3r", "zigzag", law_name, scenario="high_speed", rate=500.0,
                                    overrides={**given, **extra}))
            for name, law_name, extra in (("pd", "pd", {}), ("none", "pd_g", {"kg": 0.0}),
                                          ("full", "pd_g", {"kg": 1.0}))}
    assert np.max(np.abs(runs["none"].samples.q - runs["pd"].samples.q)) < 1e-9
    assert runs["full"].metrics.contour_mean < 0.9 * runs["pd"].metrics.contour_mean


def test_simulate_and_check_gains_take_its_gain(pd_g: None, capsys: pytest.CaptureFixture[str]) -> None:  # noqa: ARG001
    given = flags(pd_gains())
    assert cli.main(["simulate", *RUN, "--scenario", "high_speed", *given, "--gain", "kg=1"]) == 0
    assert "contour" in capsys.readouterr().out
    assert cli.main(["check-gains", *RUN, *given, "--gain", "kg=0.8", "--mode", "lockstep"]) == 0
    out = capsys.readouterr().out
    assert ", kg=[0.8]" in out and "no conditions of it for pd_g" in out and "holds" in out
    assert "ks=" not in out  # the report names the law's own gains
    assert cli.main(["check-gains", *RUN, *given, "--gain", "kg=2"]) == cli.EXIT_USAGE
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "gain kg of pd_g must be finite and >= 0 and <= 1, got [2.0]" in err[0]
    assert cli.main(["simulate", *RUN, *given]) == cli.EXIT_USAGE  # no preset, kg not given
    assert "pd_g needs gains kg: this arm has no preset for zigzag" in capsys.readouterr().err


def test_the_controller_node_declares_and_takes_it(pd_g: None) -> None:  # noqa: ARG001
    rclpy = pytest.importorskip("rclpy")
    from rclpy.parameter import Parameter

    from pdsmc_ros.controller.parameters import GainUpdates
    from pdsmc_ros.parameters.ros import declare_run_parameters
    from pdsmc_ros.ros.node_run import run_spec_from_parameters

    context = rclpy.context.Context()
    rclpy.init(context=context)
    try:
        def spec_of(overrides: dict):  # noqa: ANN202
            node = rclpy.create_node("controller", context=context,
                                     parameter_overrides=[Parameter(k, value=v) for k, v in overrides.items()])
            try:
                declare_run_parameters(node, gains=True)
                described = node.describe_parameter("kg").description
                return described, run_spec_from_parameters(node)
            finally:
                node.destroy_node()

        run = {"robot": "parallel_5r", "contour": "circle", "type": "pd_g", "scenario": "high_pd",
               "kp": [230.0, 260.0], "kd": [24.0, 36.0]}
        described, spec = spec_of({**run, "kg": 0.5})
        assert described == KG.help() and "one value for every joint" in described and "<= 1" in described
        in_process = make_run("parallel_5r", "circle", "pd_g", scenario="high_pd",
                              overrides={"kp": run["kp"], "kd": run["kd"], "kg": 0.5})
        assert spec.gains == in_process.gains and spec.gains["kg"] == (0.5,)
        with pytest.raises(ConfigError, match=r"parameters: gain kg of pd_g must be finite and >= 0 and <= 1"):
            spec_of({**run, "kg": 1.5})
        # ros2 param set kg: validated against its bounds and applied as a scalar
        node = rclpy.create_node("controller", context=context,
                                 parameter_overrides=[Parameter(k, value=v) for k, v in {**run, "kg": 0.5}.items()])
        try:
            declare_run_parameters(node, gains=True)
            applied: list = []
            GainUpdates(node, run_spec_from_parameters(node), lambda new: None, applied.append)
            assert node.set_parameters([Parameter("kg", value=0.25)])[0].successful
            assert applied[-1]["kg"] == (0.25,) and applied[-1]["kp"] == (345.0, 390.0)  # kp as started (high_pd)
            refused = node.set_parameters([Parameter("kg", value=3.0)])[0]
            assert not refused.successful and "gain kg of pd_g must be finite and >= 0 and <= 1" in refused.reason
        finally:
            node.destroy_node()
        with pytest.raises(ConfigError, match=r"parameters: pd_g needs gains kg"):
            spec_of(run)
    finally:
        rclpy.shutdown(context=context)


@pytest.mark.timeout(900)
def test_tune_writes_its_gain_and_simulate_reads_it(pd_g: None, tmp_path: Path,  # noqa: ARG001
                                                     capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "pd_g.yaml"
    assert cli.main(["tune", *RUN, "--rounds", "1", "--quiet", "--mode", "lockstep", "--out", str(out)]) == 0
    gains = yaml.safe_load(out.read_text())["controller"]["ros__parameters"]
    assert set(gains) == {"kp", "kd", "kg"} and gains["kg"] == [1.0]  # kg starts where its law declares
    capsys.readouterr()
    assert cli.main(["check-gains", *RUN, "--params-file", str(out), "--mode", "lockstep"]) == 0
    assert "kg=[1.0]" in capsys.readouterr().out
    assert cli.main(["simulate", *RUN, "--params-file", str(out), "--scenario", "high_speed"]) == 0
    assert "at 500 Hz control" in capsys.readouterr().out
