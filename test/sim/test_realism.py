"""The stand-in's nuisances resolved for an arm: presets, the rule that sizes bench, values given, and
every refusal one line naming the parameter (ROS-free)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from pdsmc_ros.sim import realism as r

UR5 = r.ArmFacts(joint_names=tuple(f"j{i}" for i in range(6)), effort_limits=np.array([150.0] * 3 + [28.0] * 3),
                 velocity_limits=np.array([3.15] * 3 + [3.2] * 3), revolute=np.ones(6, dtype=bool),
                 moving_mass=16.99, rate=1000.0)


def test_ideal_is_every_nuisance_off() -> None:
    ideal = r.resolve_realism(UR5)
    assert ideal.is_ideal and not ideal.has_physics and not ideal.has_drive
    assert ideal.summary() == "ideal: every nuisance off"
    assert set(ideal.sources.values()) == {"preset"}


def test_bench_is_sized_for_the_arm_by_its_stated_rule() -> None:
    bench = r.resolve_realism(UR5, "bench")
    # friction: 4 % of each effort limit (Coulomb), 0.06 s/rad of it (viscous): the UR10e identification
    np.testing.assert_allclose(bench.friction_coulomb, [6.0] * 3 + [1.12] * 3)
    np.testing.assert_allclose(bench.friction_viscous, [9.0] * 3 + [1.68] * 3)
    assert bench.command_delay == 2  # 2 ms at 1 kHz
    assert np.all(bench.encoder_counts == 2**18)
    np.testing.assert_allclose(bench.position_noise, 0.5 * 2 * math.pi / 2**18)
    assert bench.velocity_source == "difference"
    np.testing.assert_allclose(bench.velocity_filter_hz, 100.0)
    np.testing.assert_allclose(bench.torque_bandwidth_hz, 100.0)
    assert bench.torque_speed
    np.testing.assert_allclose(bench.no_load_speed, 2 * UR5.velocity_limits)
    assert bench.payload_mass == pytest.approx(0.925, rel=1e-3)  # a 2F-85 gripper on a UR5
    np.testing.assert_allclose(bench.payload_com, [0.0, 0.0, 0.06], rtol=1e-3)
    # another arm: the delay is a time, the tool a share of the moving mass, its offset the cube root
    small = r.ArmFacts(("a", "b"), np.array([15.0, 15.0]), np.array([15.0, 15.0]), np.ones(2, dtype=bool), 1.95,
                       5000.0)
    five_bar = r.resolve_realism(small, "bench")
    assert five_bar.command_delay == 10
    np.testing.assert_allclose(five_bar.friction_coulomb, [0.6, 0.6])
    assert five_bar.payload_mass == pytest.approx(1.95 * 0.925 / 16.99)
    assert five_bar.payload_com[2] == pytest.approx(0.06 * (five_bar.payload_mass / 0.925) ** (1 / 3))


def test_a_value_given_replaces_the_presets_and_one_value_stands_for_every_joint() -> None:
    given = r.resolve_realism(UR5, "bench", {"command_delay": 0, "friction_coulomb": 1.5,
                                             "encoder_counts": [4096] * 6, "velocity_source": None})
    assert given.command_delay == 0
    np.testing.assert_array_equal(given.friction_coulomb, [1.5] * 6)
    np.testing.assert_array_equal(given.encoder_counts, [4096] * 6)
    assert given.velocity_source == "difference"  # None: not given, the preset's
    assert given.sources["command_delay"] == "given" and given.sources["torque_speed"] == "preset"
    from_ideal = r.resolve_realism(UR5, "ideal", {"friction_viscous": [0, 1, 2, 3, 4, 5]})
    assert from_ideal.has_physics and not from_ideal.has_drive
    np.testing.assert_array_equal(from_ideal.friction_viscous, [0, 1, 2, 3, 4, 5])


@pytest.mark.parametrize(("name", "value", "message"), [
    ("friction_coulomb", -1.0, ("parameter friction_coulomb must be a list of numbers (one per joint, or one for "
                                "every joint), each in [0, 1000000], got [-1.0]")),
    ("encoder_counts", 0, ("parameter encoder_counts must be a list of whole numbers (one per joint, or one for "
                           "every joint), each in [1, 1099511627776], got [0]")),
    ("command_delay", 101, "parameter command_delay must be a whole number in [0, 100], got 101"),
    ("position_noise", [float("nan")] * 6, ("parameter position_noise must be a list of numbers (one per joint, or "
                                            "one for every joint), each in [0, 1], got [nan, nan, nan, nan, nan, "
                                            "nan]")),
    ("friction_viscous", [1.0, 2.0], ("parameter friction_viscous needs 6 values, one per joint (or one for every "
                                      "joint), got 2")),
    ("velocity_source", "filtered", "parameter velocity_source must be one of: exact, difference, got 'filtered'"),
    ("torque_speed", 1, "parameter torque_speed must be true or false, got 1"),
    ("no_load_speed", 0.0, ("parameter no_load_speed must be a list of numbers (one per joint, or one for every "
                            "joint), each > 0 and <= 1000000, got [0.0]")),
    ("payload_com", [0.0, 0.1], "parameter payload_com needs 3 values, got 2"),
    ("command_delay", 1.5, "parameter command_delay must be a whole number in [0, 100], got 1.5"),
])
def test_a_bad_value_is_one_line_naming_the_parameter(name: str, value: object, message: str) -> None:
    with pytest.raises(r.RealismError) as caught:
        r.resolve_realism(UR5, "bench", {name: value})
    assert str(caught.value) == message
    assert "\n" not in str(caught.value)


def test_a_bad_preset_seed_or_name_is_refused() -> None:
    with pytest.raises(r.RealismError, match="parameter realism must be one of: ideal, bench, got 'lab'"):
        r.resolve_realism(UR5, "lab")
    with pytest.raises(r.RealismError, match="parameter seed must be a whole number in"):
        r.resolve_realism(UR5, seed=-1)
    with pytest.raises(r.RealismError, match="unknown nuisance 'friction'"):
        r.resolve_realism(UR5, given={"friction": 1.0})


def test_torque_speed_needs_the_limits_it_starts_from() -> None:
    no_limits = r.ArmFacts(("a",), np.array([np.inf]), np.array([np.inf]), np.ones(1, dtype=bool), 1.0, 1000.0)
    with pytest.raises(r.RealismError, match="parameter torque_speed needs each joint's effort limit; joint 'a'"):
        r.resolve_realism(no_limits, given={"torque_speed": True})
    limited = r.ArmFacts(("a",), np.array([10.0]), np.array([np.inf]), np.ones(1, dtype=bool), 1.0, 1000.0)
    with pytest.raises(r.RealismError, match="no_load_speed: joint 'a' has no velocity limit"):
        r.resolve_realism(limited, given={"torque_speed": True})
    assert r.resolve_realism(limited, given={"torque_speed": True, "no_load_speed": 5.0}).no_load_speed[0] == 5.0
    # bench on an arm without an effort limit: no friction to scale, no torque-speed line to start from
    bench = r.resolve_realism(no_limits, "bench", {"torque_speed": False})
    assert bench.friction_coulomb[0] == 0.0


def test_the_declarations_are_the_drivers_parameters() -> None:
    from pdsmc_ros.parameters import mujoco_driver_parameters

    names = [p.name for p in mujoco_driver_parameters()]
    for name in (*r.SETTINGS, *r.NUISANCES):
        assert name in names
    live = {p.name for p in mujoco_driver_parameters() if not p.read_only}
    assert live == set(r.NUISANCES) - {"payload_mass", "payload_com"}  # the model's are read at start-up
