"""Joints by name, standard JointTrajectory interpolation and the generated URDF (ROS-free core)."""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pdsmc_ros.bag import cdr
from pdsmc_ros.controller.joint_trajectory import JointTrajectoryReference, TrajectoryRules
from pdsmc_ros.controller.joints import JointSelector
from pdsmc_ros.errors import CdrError, ConfigError
from pdsmc_ros.parameters.joint_map import check_joint_names
from pdsmc_ros.robots import Parallel5R, Serial3R, robot_params
from pdsmc_ros.robots.urdf import robot_urdf

JOINTS = ("joint1", "joint2", "joint3")


def test_selector_matches_by_name_in_any_order_and_ignores_extra_joints() -> None:
    sel = JointSelector(JOINTS)
    names = ("gripper", "joint3", "joint1", "joint2")
    (q, qd), reason = sel.select(names, ("position", "velocity"), (9.0, 3.0, 1.0, 2.0), (9.0, 30.0, 10.0, 20.0))
    assert reason == ""
    np.testing.assert_array_equal(q, [1.0, 2.0, 3.0])
    np.testing.assert_array_equal(qd, [10.0, 20.0, 30.0])
    # in order with extra joints after: a prefix
    (q,), reason = sel.select(JOINTS + ("joint4",), ("position",), (1.0, 2.0, 3.0, 4.0))
    np.testing.assert_array_equal(q, [1.0, 2.0, 3.0])


def test_selector_caches_the_permutation_per_name_list() -> None:
    sel = JointSelector(JOINTS)
    names = ("joint2", "joint1", "joint3")
    first = sel.index(names)[0]
    assert sel.index(tuple(list(names)))[0] is first  # noqa: C414 (equal names, another tuple object: from the cache)
    assert sel.index(names)[0] is first


@pytest.mark.parametrize(("names", "position", "velocity", "needle"), [
    (("joint1", "joint3"), (1.0, 2.0), (0.0, 0.0), "'joint2' missing"),
    (("joint3", "joint2", "joint1"), (1.0, 2.0), (0.0, 0.0, 0.0), "position has 2 values"),
    (("joint3", "joint2", "joint1"), (1.0, 2.0, 3.0), (), "velocity has 0 values"),
    (JOINTS, (1.0, float("nan"), 3.0), (0.0, 0.0, 0.0), "position of joint 'joint2' is not finite"),
    (("joint3", "joint2", "joint1"), (1.0, 2.0, 3.0), (0.0, 0.0, float("inf")),
     "velocity of joint 'joint1' is not finite"),
    ((), (), (), "missing"),
])
def test_selector_refuses_incomplete_or_non_finite_states(names, position, velocity, needle) -> None:  # noqa: ANN001
    arrays, reason = JointSelector(JOINTS).select(names, ("position", "velocity"), position, velocity)
    assert len(arrays) == 0 and needle in reason


@settings(max_examples=200, deadline=None)
@given(st.lists(st.text(max_size=4), max_size=6),
       st.lists(st.floats(allow_nan=True, allow_infinity=True), max_size=8))
def test_selector_never_raises(names: list[str], values: list[float]) -> None:
    arrays, reason = JointSelector(JOINTS).select(tuple(names), ("position", "velocity"), values, values)
    if reason:
        assert len(arrays) == 0
    else:
        assert len(arrays) == 2 and all(a.shape == (3,) and np.all(np.isfinite(a)) for a in arrays)


def test_check_joint_names() -> None:
    assert check_joint_names(["a", "b"], 2) == ("a", "b")
    for bad in (["a"], ["a", "a"], "ab", ["a", 3], ["a", ""]):
        with pytest.raises(ConfigError, match="parameter joints"):
            check_joint_names(bad, 2)


def test_decode_names_of_the_loop_messages_and_malformed_bytes() -> None:
    names = ["b", "a", "c"]
    data = cdr.encode_joint_state(1, 2, names, [1.0, 2.0, 3.0], [4.0, 5.0, 6.0], [])
    first = cdr.decode_joint_state_named(data)
    again = cdr.decode_joint_state_named(data)  # the fast path: the same names object
    assert first[0] == ("b", "a", "c") and again[0] is first[0] and again[1:] == first[1:]
    ref = cdr.encode_joint_trajectory(3, 4, names, [1.0, 2.0, 3.0], [0.0] * 3, [0.0] * 3)
    assert cdr.decode_joint_trajectory_named(ref)[0] == ("b", "a", "c")
    sec, nanosec, got, points = cdr.decode_joint_trajectory_points(ref)
    assert (sec, nanosec, got) == (3, 4, ("b", "a", "c")) and points == [
        ((1.0, 2.0, 3.0), (0.0,) * 3, (0.0,) * 3, 0, 0)
    ]
    for cut in (5, 13, 20, len(data) - 3):
        with pytest.raises(CdrError):
            cdr.decode_joint_state_named(data[:cut])
    with pytest.raises(CdrError):
        cdr.decode_joint_trajectory_points(ref[:-6])


def _points_message(points: list[tuple[list[float], list[float], list[float], float]],
                    names: tuple[str, ...] = ("j1", "j2")) -> tuple[tuple[str, ...], list]:
    raw = [(p, v, a, int(t), int(round((t - int(t)) * 1e9))) for p, v, a, t in points]
    return names, raw


def _reference(points, names=("j1", "j2"), *, stamp=0.0, now=10.0, q=(0.0, 0.0), qd=(0.0, 0.0)):  # noqa: ANN001, ANN202
    names, raw = _points_message(points, names)
    ref, reason = JointTrajectoryReference.from_message(
        JointSelector(("j1", "j2")), stamp, names, raw, now, np.array(q), np.array(qd),
        TrajectoryRules(allow_nonzero_velocity_at_trajectory_end=True))  # the cubic test ends moving
    assert reason == "", reason
    return ref


def test_linear_interpolation_with_positions_only() -> None:
    ref = _reference([([1.0, 2.0], [], [], 1.0), ([3.0, 2.0], [], [], 2.0)], q=(0.0, 4.0))
    q, qd, qdd = ref.sample(10.5)  # halfway from the state at receipt (t = 10) to point 0 (t = 11)
    np.testing.assert_allclose(q, [0.5, 3.0]), np.testing.assert_allclose(qd, [1.0, -2.0])
    q, qd, qdd = ref.sample(11.25)
    np.testing.assert_allclose(q, [1.5, 2.0]), np.testing.assert_allclose(qd, [2.0, 0.0])
    np.testing.assert_array_equal(qdd, [0.0, 0.0])
    q, qd, qdd = ref.sample(20.0)  # after the last point: held at zero velocity
    np.testing.assert_array_equal(q, [3.0, 2.0]), np.testing.assert_array_equal(qd, [0.0, 0.0])


def test_cubic_and_quintic_segments_meet_their_end_conditions() -> None:
    p0, v0, a0 = [0.0, 1.0], [0.5, -1.0], [2.0, 0.0]
    p1, v1, a1 = [1.0, -1.0], [0.0, 2.0], [-1.0, 3.0]
    for accelerations in (True, False):
        pts = [(p0, v0, a0 if accelerations else [], 1.0), (p1, v1, a1 if accelerations else [], 3.0)]
        ref = _reference(pts, q=p0, qd=v0)
        for t, (p, v) in ((11.0, (p0, v0)), (13.0 - 1e-12, (p1, v1))):
            q, qd, qdd = ref.sample(t)
            np.testing.assert_allclose(q, p, atol=1e-9), np.testing.assert_allclose(qd, v, atol=1e-9)
        if accelerations:
            np.testing.assert_allclose(ref.sample(11.0)[2], a0, atol=1e-9)
            np.testing.assert_allclose(ref.sample(13.0 - 1e-12)[2], a1, atol=1e-6)
        # velocity is the derivative of position, acceleration that of velocity
        t, h = 12.3, 1e-6
        (qa, va, _), (qb, vb, _) = ref.sample(t - h), ref.sample(t + h)
        q, qd, qdd = ref.sample(t)
        np.testing.assert_allclose((qb - qa) / (2 * h), qd, atol=1e-6)
        np.testing.assert_allclose((vb - va) / (2 * h), qdd, atol=1e-5)


def test_header_stamp_and_joint_order() -> None:
    # stamped 1 s before receipt: point 0 (time_from_start 2 s) is 1 s after receipt
    ref = _reference([([2.0, 1.0], [], [], 2.0)], names=("j2", "j1"), stamp=9.0, now=10.0)
    np.testing.assert_allclose(ref.sample(10.5)[0], [0.5, 1.0])  # j1 -> 1 from 0, j2 -> 2 from 0


@pytest.mark.parametrize(("points", "names", "stamp", "needle"), [
    ([], ("j1", "j2"), 0.0, "without points"),
    ([([1.0], [], [], 1.0)], ("j1",), 0.0, "'j2' missing"),
    ([([1.0, 2.0], [0.0], [], 1.0)], ("j1", "j2"), 0.0, "1 velocities for 2"),
    ([([1.0, math.nan], [], [], 1.0)], ("j1", "j2"), 0.0, "not finite"),
    ([([1.0, 2.0], [], [], 1.0), ([1.0, 2.0], [], [], 1.0)], ("j1", "j2"), 0.0, "not after"),
    ([([1.0, 2.0], [], [], 1.0)], ("j1", "j2"), 1.0, "ends 8.000 s before"),
    ([([1.0, 2.0], [], [], 1.0)], ("j1", "j1"), 0.0, "repeats"),
])
def test_refused_trajectories(points, names, stamp, needle) -> None:  # noqa: ANN001
    names, raw = _points_message(points, names)
    ref, reason = JointTrajectoryReference.from_message(
        JointSelector(("j1", "j2")), stamp, names, raw, 10.0, np.zeros(2), np.zeros(2))
    assert ref is None and needle in reason


def _urdf_tip(urdf: str, q: dict[str, float], tip: str = "tool0") -> np.ndarray:
    """Planar forward kinematics read from the URDF: (x, z) of ``tip``'s origin."""
    joints = {j.find("child").get("link"): j for j in ET.fromstring(urdf).iter("joint")}
    x = z = angle = 0.0
    chain = []
    link = tip
    while link in joints:
        chain.append(joints[link])
        link = joints[link].find("parent").get("link")
    for joint in reversed(chain):
        ox = float(joint.find("origin").get("xyz").split()[0])
        x, z = x + ox * math.cos(angle), z + ox * math.sin(angle)
        if joint.get("type") == "revolute":
            assert joint.find("axis").get("xyz") == "0 -1 0"
            angle += q[joint.get("name")]
    return np.array([x, z])


def test_urdf_tips_match_the_models_kinematics() -> None:
    rng = np.random.default_rng(5)
    serial = Serial3R()
    urdf = robot_urdf("serial_3r", robot_params("serial_3r"), payload=1.5)
    ET.fromstring(urdf)  # well-formed
    assert urdf.count("<joint ") == 5 and 'damping="0.07"' in urdf
    for _ in range(5):
        q = rng.uniform(-3, 3, 3)
        got = _urdf_tip(urdf, {f"joint{i + 1}": q[i] for i in range(3)})
        np.testing.assert_allclose(got, serial.forward_kinematics(q)[:2], atol=1e-12)
    five = Parallel5R()
    urdf = robot_urdf("parallel_5r", robot_params("parallel_5r"))
    from pdsmc_ros.sim import PlantStepper

    q0 = five.inverse_kinematics(np.array([0.10, 0.18]))
    plant = PlantStepper(five, 1e-3, q0, np.zeros(2))
    out = plant.outputs()
    named = {"joint1": q0[0], "joint2": q0[1], "joint3": out[2], "joint4": out[3]}
    np.testing.assert_allclose(_urdf_tip(urdf, named, "tool0"), out[:2], atol=1e-9)
    # the loop closure: the right chain's distal link ends at the same point
    right = _urdf_tip(urdf, named, "link4") + 0.25 * np.array(
        [math.cos(q0[1] + out[3]), math.sin(q0[1] + out[3])])
    np.testing.assert_allclose(right, out[:2], atol=1e-9)
    with pytest.raises(ValueError, match="no URDF"):
        robot_urdf("delta", robot_params("serial_3r"))


@pytest.mark.parametrize("names", [JOINTS, ("joint2", "joint1", "joint3"), JOINTS + ("joint4",)])
@pytest.mark.parametrize("bad", [None, math.nan, math.inf, "short"])
def test_state_and_reference_short_paths_equal_select(names: tuple[str, ...], bad: object) -> None:
    """The controller's per-step calls give select's arrays and reasons, whichever path they take."""
    sel, ref_sel = JointSelector(JOINTS), JointSelector(JOINTS)
    values = [float(i + 1) for i in range(len(names))]
    if bad == "short":
        values = values[:-1]
    elif bad is not None:
        values[1] = bad
    columns = (tuple(values), tuple(v * 10 for v in values), tuple(v * 100 for v in values))
    usable = bad is None or (bad == "short" and len(names) > len(JOINTS))  # only joint4 lost a value
    for _ in range(2):  # the first call learns the name list, the second takes the short path
        got, reason = sel.state(names, *columns[:2])
        want, want_reason = JointSelector(JOINTS).select(names, ("position", "velocity"), *columns[:2])
        assert reason == want_reason and usable == (reason == "")
        for a, b in zip(got, want):
            np.testing.assert_array_equal(a, b)
        got, reason = ref_sel.reference(names, *columns)
        want, want_reason = JointSelector(JOINTS).select(
            names, ("positions", "velocities", "accelerations"), *columns)
        assert reason == want_reason and usable == (reason == "")
        for a, b in zip(got, want):
            np.testing.assert_array_equal(a, b)
