"""The hand-written CDR codecs of the control loop against rclpy's own serialization."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pdsmc_ros.bag import cdr
from pdsmc_ros.errors import CdrError

NAMES = [["joint_1", "joint_2", "joint_3"], ["q1", "q2", "q3", "q4"], [], ["x"]]


@pytest.mark.parametrize("names", NAMES)
@pytest.mark.parametrize("m", [0, 1, 2, 3])
def test_codecs_round_trip(names: list[str], m: int) -> None:
    rng = np.random.default_rng(m + len(names))
    p, v, e = (rng.normal(size=m).tolist() for _ in range(3))
    assert cdr.decode_joint_state(cdr.encode_joint_state(7, 123, names, p, v, e)) == (
        7,
        123,
        tuple(p),
        tuple(v),
        tuple(e),
    )
    assert cdr.decode_joint_trajectory(cdr.encode_joint_trajectory(1, 2, names, p, v, e)) == (
        1,
        2,
        tuple(p),
        tuple(v),
        tuple(e),
    )
    assert cdr.decode_float64_multi_array(cdr.encode_float64_multi_array(p, 99)) == (99, tuple(p))
    assert cdr.decode_stamp(cdr.encode_joint_state(-3, 5, names, p, v, e)) == (-3, 5)


@pytest.mark.parametrize("names", NAMES)
@pytest.mark.parametrize("m", [0, 1, 3])
def test_codecs_match_rclpy(names: list[str], m: int) -> None:
    """rclpy reads our bytes back to the same message and we read rclpy's bytes
    (byte equality is not expected: rclpy's padding bytes are uninitialised and its
    buffer carries worst-case trailing padding)."""
    serialization = pytest.importorskip("rclpy.serialization")
    from builtin_interfaces.msg import Time
    from sensor_msgs.msg import JointState
    from std_msgs.msg import Float64MultiArray
    from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

    rng = np.random.default_rng(3)
    p, v, e = (rng.normal(size=m).tolist() for _ in range(3))
    js = JointState(name=names, position=p, velocity=v, effort=e)
    js.header.stamp = Time(sec=12, nanosec=345)
    point = JointTrajectoryPoint(positions=p, velocities=v, accelerations=e)
    jt = JointTrajectory(joint_names=names, points=[point])
    jt.header.stamp = Time(sec=1, nanosec=2)
    fa = Float64MultiArray(data=p)
    fa.layout.data_offset = 41
    cases = [
        (
            js,
            cdr.encode_joint_state(12, 345, names, p, v, e),
            cdr.decode_joint_state,
            (12, 345, tuple(p), tuple(v), tuple(e)),
        ),
        (
            jt,
            cdr.encode_joint_trajectory(1, 2, names, p, v, e),
            cdr.decode_joint_trajectory,
            (1, 2, tuple(p), tuple(v), tuple(e)),
        ),
        (fa, cdr.encode_float64_multi_array(p, 41), cdr.decode_float64_multi_array, (41, tuple(p))),
    ]
    for msg, ours, decode, fields in cases:
        theirs = serialization.serialize_message(msg)
        assert len(ours) <= len(theirs)
        assert serialization.deserialize_message(ours, type(msg)) == msg
        assert decode(theirs) == fields


def test_decoders_refuse_what_the_loop_does_not_produce() -> None:
    with pytest.raises(CdrError, match="little-endian CDR"):
        cdr.decode_joint_state(b"\x00\x00\x00\x00")
    with_dims = bytearray(cdr.encode_float64_multi_array([1.0]))
    with_dims[4] = 1  # one layout dimension
    with pytest.raises(CdrError, match="layout dimensions"):
        cdr.decode_float64_multi_array(bytes(with_dims))
    with pytest.raises(CdrError, match="layout dimensions"):
        cdr.float64_multi_array_offset(bytes(with_dims))
    empty = cdr.encode_joint_trajectory(0, 0, ["a"], [], [], [])
    no_points = empty[: empty.index(b"a\x00") + 4] + b"\x00\x00\x00\x00"
    assert cdr.decode_joint_trajectory(no_points) is None


@pytest.mark.parametrize("names", NAMES)
@pytest.mark.parametrize("m", [0, 1, 3])
def test_codecs_are_byte_identical_to_rosbags(names: list[str], m: int) -> None:
    """rosbags' serializer (zero padding, no trailing bytes) writes exactly our bytes."""
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_JAZZY)
    p, v, e = ([0.5 * k + i for i in range(m)] for k in range(3))
    for ours, msgtype in (
        (cdr.encode_joint_state(4, 5, names, p, v, e), "sensor_msgs/msg/JointState"),
        (cdr.encode_joint_trajectory(4, 5, names, p, v, e), "trajectory_msgs/msg/JointTrajectory"),
        (cdr.encode_float64_multi_array(p, 6), "std_msgs/msg/Float64MultiArray"),
    ):
        assert store.serialize_cdr(store.deserialize_cdr(ours, msgtype), msgtype) == ours


finite = st.floats(allow_nan=False, width=64)
shapes = st.tuples(
    st.lists(st.sampled_from(["a", "b", "ab", "q1", "q2", "joint_1"]), max_size=4),  # joint names
    st.integers(0, 4), st.integers(-5, 5), st.integers(0, 10**9 - 1),  # doubles per field, stamp
)


@settings(max_examples=300, deadline=None)
@given(st.lists(st.tuples(shapes, st.data()), min_size=1, max_size=12))
def test_remembered_layouts_never_mix_up_messages(messages) -> None:  # noqa: ANN001
    """Encoders and decoders reuse the layout of a shape they have seen (one pack or
    unpack); messages of equal length but other names or counts must still read back
    exactly, in any order, as must rclpy-style bytes with garbage in the padding."""
    for (names, m, sec, nanosec), data in messages:
        p, v, e = (data.draw(st.lists(finite, min_size=m, max_size=m)) for _ in range(3))
        js = cdr.encode_joint_state(sec, nanosec, names, p, v, e)
        assert cdr.decode_joint_state(js) == (sec, nanosec, tuple(p), tuple(v), tuple(e))
        jt = cdr.encode_joint_trajectory(sec, nanosec, names, p, v, e)
        assert cdr.decode_joint_trajectory(jt) == (sec, nanosec, tuple(p), tuple(v), tuple(e))
        fa = cdr.encode_float64_multi_array(p, nanosec)
        assert cdr.decode_float64_multi_array(fa) == (nanosec, tuple(p))
        assert cdr.decode_stamp(js) == cdr.decode_stamp(jt) == (sec, nanosec)
        assert cdr.float64_multi_array_offset(fa) == nanosec
        # a writer that leaves garbage in its padding (rclpy does) is read field by field
        dirty = bytearray(js)
        spans = cdr.joint_state_spans(js)
        pad = spans["position"][0] - 4
        if m and dirty[pad:pad + 4] == b"\x00" * 4 and (pad - 4) % 8 == 4:
            dirty[pad:pad + 4] = b"\xff" * 4
            assert cdr.decode_joint_state(bytes(dirty)) == (sec, nanosec, tuple(p), tuple(v), tuple(e))


def test_the_loop_messages_take_the_one_pack_path() -> None:
    """After one message of a shape, the same shape is written and read by its layout."""
    names = ["joint_1", "joint_2", "joint_3"]
    first = cdr.encode_joint_state(1, 2, names, [1.0] * 3, [2.0] * 3, [3.0] * 3)
    cdr.decode_joint_state(first)
    key = ("js", "", *names, 3, 3, 3)
    assert key in cdr._encode_layouts and ("js", len(first)) in cdr._decode_layouts
    again = cdr.encode_joint_state(5, 6, names, [0.5] * 3, [0.25] * 3, [0.0] * 3)
    general = cdr._Writer()
    general.header_and_names(5, 6, "", names)
    for values in ([0.5] * 3, [0.25] * 3, [0.0] * 3):
        general.doubles(values)
    assert again == bytes(general.buf)
    assert cdr._decode_layouts[("js", len(first))].read(again) == ((5, 6), (0.5,) * 3, (0.25,) * 3, (0.0,) * 3)


@pytest.mark.parametrize("frame_id", ["", "world", "base_link_x"])
def test_clock_and_point_codecs_match_rclpy_and_rosbags(frame_id: str) -> None:
    """The plant's /clock and the end-effector points: rclpy reads our bytes back, and
    rosbags writes exactly our bytes (twice: the second goes through the remembered layout)."""
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_JAZZY)
    serialization = pytest.importorskip("rclpy.serialization")
    from geometry_msgs.msg import PointStamped
    from rosgraph_msgs.msg import Clock

    for k in range(2):
        sec, nanosec, x, y = 7 + k, 123 + k, 0.25 - k, -1.5 + k
        clock = cdr.encode_clock(sec, nanosec)
        point = cdr.encode_point_stamped(sec, nanosec, x, y, frame_id=frame_id)
        msg = serialization.deserialize_message(clock, Clock)
        assert (msg.clock.sec, msg.clock.nanosec) == (sec, nanosec)
        msg = serialization.deserialize_message(point, PointStamped)
        assert (msg.header.stamp.sec, msg.header.stamp.nanosec, msg.header.frame_id) == (sec, nanosec, frame_id)
        assert (msg.point.x, msg.point.y, msg.point.z) == (x, y, 0.0)
        for ours, msgtype in ((clock, "rosgraph_msgs/msg/Clock"), (point, "geometry_msgs/msg/PointStamped")):
            assert store.serialize_cdr(store.deserialize_cdr(ours, msgtype), msgtype) == ours


@pytest.mark.parametrize("n", [2, 3])
def test_trajectory_block_encoder_equals_one_by_one(n: int) -> None:
    """The trajectory's windowed encoder writes exactly encode_joint_trajectory's bytes."""
    rng = np.random.default_rng(7 + n)
    count = 50
    names = [f"joint_{i + 1}" for i in range(n)]
    q, qd, qdd = (rng.normal(scale=s, size=(count, n)) for s in (1.0, 10.0, 1e3))
    stamps = [(int(s), int(ns)) for s, ns in zip(rng.integers(0, 2**31 - 1, count), rng.integers(0, 10**9, count))]
    block = cdr.encode_joint_trajectories(stamps, names, q, qd, qdd)
    assert block == [cdr.encode_joint_trajectory(s, ns, names, q[k].tolist(), qd[k].tolist(), qdd[k].tolist())
                     for k, (s, ns) in enumerate(stamps)]
    assert cdr.encode_joint_trajectories([], names, q[:0], qd[:0], qdd[:0]) == []
