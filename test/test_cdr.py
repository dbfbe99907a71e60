"""The hand-written CDR codecs of the control loop against rclpy's own serialization."""

from __future__ import annotations

import numpy as np
import pytest

from pdsmc_ros import cdr
from pdsmc_ros.errors import BagError

NAMES = [["joint_1", "joint_2", "joint_3"], ["q1", "q2", "q3", "q4"], [], ["x"]]


@pytest.mark.parametrize("names", NAMES)
@pytest.mark.parametrize("m", [0, 1, 2, 3])
def test_codecs_round_trip(names: list[str], m: int) -> None:
    rng = np.random.default_rng(m + len(names))
    p, v, e = (rng.normal(size=m).tolist() for _ in range(3))
    assert cdr.decode_joint_state(cdr.encode_joint_state(7, 123, names, p, v, e)) == (7, 123, tuple(p), tuple(v), tuple(e))
    assert cdr.decode_joint_trajectory(cdr.encode_joint_trajectory(1, 2, names, p, v, e)) == (1, 2, tuple(p), tuple(v), tuple(e))
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
        (js, cdr.encode_joint_state(12, 345, names, p, v, e), cdr.decode_joint_state, (12, 345, tuple(p), tuple(v), tuple(e))),
        (jt, cdr.encode_joint_trajectory(1, 2, names, p, v, e), cdr.decode_joint_trajectory, (1, 2, tuple(p), tuple(v), tuple(e))),
        (fa, cdr.encode_float64_multi_array(p, 41), cdr.decode_float64_multi_array, (41, tuple(p))),
    ]
    for msg, ours, decode, fields in cases:
        theirs = serialization.serialize_message(msg)
        assert len(ours) <= len(theirs)
        assert serialization.deserialize_message(ours, type(msg)) == msg
        assert decode(theirs) == fields


def test_decoders_refuse_what_the_loop_does_not_produce() -> None:
    with pytest.raises(BagError, match="little-endian CDR"):
        cdr.decode_joint_state(b"\x00\x00\x00\x00")
    with_dims = bytearray(cdr.encode_float64_multi_array([1.0]))
    with_dims[4] = 1  # one layout dimension
    with pytest.raises(BagError, match="layout dimensions"):
        cdr.decode_float64_multi_array(bytes(with_dims))
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
