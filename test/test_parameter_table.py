"""The parameter tables (ROS-free): each parameter declared once, its start-up and on-set checks
derived from the declaration, the gains derived from the law registry, the catalog for the docs,
and the one gain resolver."""

from __future__ import annotations

import json
import math
from collections.abc import Iterator

import numpy as np
import pytest

from pdsmc_ros.control import GainSpec, LawEntry, LawSetup, register_law, unregister_law
from pdsmc_ros.errors import ConfigError
from pdsmc_ros.parameters import NODES, ParameterSpec, catalog, gain_parameters, node_parameters
from pdsmc_ros.parameters import params_file as settings
from pdsmc_ros.parameters.tables import MAX_LOOKAHEAD_STEPS
from pdsmc_ros.runs.builder import make_run, resolve_gains

ODD_VALUES = [None, True, False, 0, -1, 3, 2.5, math.nan, math.inf, -math.inf, 1e308, "", "abc", b"\x01",
              [], [True], [True] * 6, [1, 2], [1.0], [1e308] * 6, [math.nan] * 3, ["a"], [[1.0]], {"a": 1},
              object(), [object()], (1.0, 2.0)]


def spec(node: str, name: str) -> ParameterSpec:
    return next(s for s in node_parameters(node) if s.name == name)


@pytest.mark.parametrize("node", NODES)
def test_each_node_declares_each_name_once_and_its_defaults_pass_its_checks(node: str) -> None:
    specs = node_parameters(node)
    names = [s.name for s in specs]
    assert len(names) == len(set(names)), node
    for s in specs:
        assert s.problem(s.default) is None, (node, s.name, s.default)
        assert s.description and s.allowed()


@pytest.mark.parametrize("node", NODES)
def test_no_value_makes_a_check_raise(node: str) -> None:
    """The on-set check returns a one-line reason, never an exception, whatever it is given."""
    for s in node_parameters(node):
        for value in ODD_VALUES:
            reason = s.problem(value, 6)
            assert reason is None or (isinstance(reason, str) and "\n" not in reason and s.name in reason)


def test_the_findings_of_issue_37_are_refused_by_the_table() -> None:
    kp = spec("controller", "kp")
    assert kp.type == "double_array" and not kp.read_only
    for value in ([True] * 6, [math.nan] * 6, [math.inf] * 6, "abcdef", 3000.0, True):
        assert kp.problem(value, 6), value  # a bool array is not a double array; a scalar is not an array
    assert kp.problem([1.0, 2.0], 6) == "parameter kp needs 6 values, one per joint (or one for every joint), got 2"
    assert kp.problem([3000.0], 6) is None and kp.problem([3000.0] * 6, 6) is None
    # what the controller does not apply at run time is read-only (rclpy refuses the set)
    writable = {s.name for s in node_parameters("controller") if not s.read_only}
    assert writable == {g.name for g in gain_parameters(applied=True)}
    for node in NODES:
        if node != "controller":
            assert all(s.read_only for s in node_parameters(node)), node
    for name in ("stability_margin", "delay_periods", "busy_wait", "thread_priority", "joints", "rate"):
        assert spec("controller", name).read_only, name


@pytest.mark.parametrize(("node", "name", "value", "message"), [
    ("trajectory", "lookahead_steps", 0, "parameter lookahead_steps must be a whole number in [1, 5000], got 0"),
    ("controller", "stale_periods", 2.5, "parameter stale_periods must be a whole number in [1, 1000000], got 2.5"),
    ("plant", "expected_subscribers", "many",
     "parameter expected_subscribers must be a whole number in [0, 100], got 'many'"),
    ("trajectory", "busy_wait", "fast",
     "parameter busy_wait must be -1 (automatic) or a number of seconds in [0, 1], got 'fast'"),
    ("trajectory", "busy_wait", -0.5,
     "parameter busy_wait must be -1 (automatic) or a number of seconds in [0, 1], got -0.5"),
    ("plant", "rate", -5.0, "parameter rate must be a number in [0, 1e+06], got -5.0"),
    ("plant", "rate", True, "parameter rate must be a number in [0, 1e+06], got True"),
    ("controller", "mode", "fast", "parameter mode must be one of: lockstep, realtime, got 'fast'"),
    ("controller", "autostart", 1, "parameter autostart must be true or false, got 1"),
    ("controller", "torque_limit", [1.0, 0.0], ("parameter torque_limit must be a list of numbers (one per joint), "
                                               "each > 0, got [1.0, 0.0]")),
    ("viewer", "display_rate", 0.0, "parameter display_rate must be a number > 0 and <= 240, got 0.0"),
])
def test_start_up_values_are_refused_in_one_line_naming_the_parameter(node: str, name: str, value: object,
                                                                       message: str) -> None:
    with pytest.raises(ConfigError) as raised:
        spec(node, name).start_value(value)
    assert str(raised.value) == message


def test_start_up_takes_what_yaml_and_the_command_line_write() -> None:
    assert spec("controller", "rate").coerce(1000) == 1000.0 and isinstance(spec("controller", "rate").coerce(1000),
                                                                            float)
    assert spec("controller", "kp").coerce([8000, 8000, 3000]) == [8000.0, 8000.0, 3000.0]
    assert spec("controller", "kp").coerce(3000.0) == [3000.0]  # -p kp:=3000.0 at start: every joint
    assert spec("controller", "kp").coerce([]) is None  # empty: the preset
    assert spec("controller", "cpu_affinity").coerce(1) == [1]
    assert spec("trajectory", "busy_wait").coerce(-1) == -1.0 and spec("trajectory", "busy_wait").problem(-1.0) is None
    with pytest.raises(ConfigError, match=r"^parameter kp must be a list of numbers .*, got \[True, True\]$"):
        spec("controller", "kp").coerce([True, True])


KI = GainSpec("k_test", "a test law's own gain", "N m/rad", start=0.0)  # a gain no other law declares


@pytest.fixture
def pid() -> Iterator[None]:
    def torque(setup: LawSetup, q, qd, q_ref, qd_ref, qdd_ref):  # noqa: ANN001, ANN202, ARG001
        return setup.gains[0] * (q_ref - q) + setup.gains[1] * (qd_ref - qd)

    register_law(LawEntry("pid_test", "PID", ("kp", "kd", KI), torque, "a test's own law"))
    yield
    unregister_law("pid_test")


def test_a_registered_laws_gain_is_declared_like_the_built_in_ones(pid: None) -> None:  # noqa: ARG001
    gain = spec("controller", "k_test")
    assert gain.type == "double_array" and gain.per_joint and gain.description == KI.help() and not gain.read_only
    assert spec("plant", "k_test").read_only
    assert "k_test" in {p["name"] for p in catalog()["controller"]}
    assert "k_test" in settings.controller_parameters() and "k_test" in settings.PACKAGE_PARAMETERS
    # the controller applies only its own law's gains: a PD controller's k_test is read-only
    pd = {s.name: s.read_only for s in gain_parameters(applied=("kp", "kd"))}
    assert not pd["kp"] and pd["k_test"] and pd["ks"]


def test_the_catalog_is_plain_data_for_every_node() -> None:
    data = catalog()
    assert set(data) == set(NODES)
    json.dumps(data, allow_nan=False)
    kp = next(p for p in data["controller"] if p["name"] == "kp")
    assert kp["type"] == "double_array" and kp["per_joint"] and kp["read_only"] is False and kp["lower"] == 0.0
    busy = next(p for p in data["trajectory"] if p["name"] == "busy_wait")
    assert busy["default"] == -1.0 and busy["special"] == [-1.0] and busy["read_only"]


def test_settings_derives_the_names_from_the_tables() -> None:
    gains = {g.name for g in gain_parameters(applied=True)}
    assert set(settings.CONTROLLER_PARAMETERS) == {s.name for s in node_parameters("controller")} - gains
    assert {"watchdog_timeout", "lookahead_steps", "output", "substeps", "port"} <= settings.PACKAGE_PARAMETERS


def test_the_lookahead_bound_is_half_the_streams_depth() -> None:
    pytest.importorskip("rclpy")
    from pdsmc_ros.ros.topics import STREAM_DEPTH

    assert STREAM_DEPTH // 2 == MAX_LOOKAHEAD_STEPS


def test_one_resolver_orders_layers_joints_and_the_scenario() -> None:
    """Presets, then each layer (in ``joints`` order, one value for every joint, empty: not given),
    then the scenario's factors on whatever layer gave each gain."""
    order = [2, 0, 1]  # joints:=[joint3, joint1, joint2]
    given = {"kp": [3000.0, 8000.0, 7000.0], "kd": [150.0]}
    gains = resolve_gains("serial_3r", "circle", "pd", scenario="high_pd", layers=[given, {"kd": []}],
                          joint_order=order)
    np.testing.assert_array_equal(gains["kp"], [1.5 * 8000.0, 1.5 * 7000.0, 1.5 * 3000.0])
    np.testing.assert_array_equal(gains["kd"], [1.5 * 150.0] * 3)
    spec_ = make_run("serial_3r", "circle", "pd", scenario="high_pd", overrides=given, joint_order=order)
    assert spec_.gains == gains
    with pytest.raises(ConfigError, match="gain kp needs 3 values"):
        resolve_gains("serial_3r", "circle", "pd", layers=[{"kp": [1.0, 2.0]}], joint_order=order)
