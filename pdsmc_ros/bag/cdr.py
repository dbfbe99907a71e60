"""CDR (XCDR1, little endian) encoding of the messages of the control loop.

The lockstep nodes publish and take serialized messages (``raw=True``): building
a ``JointState`` in Python and converting it to C costs more than the control
law. These functions write what rclpy's ``serialize_message`` writes (rclpy reads
it back unchanged; rosbags' serializer writes the very same bytes, tested), and read
back the fields the nodes use; the bag reader
(:mod:`pdsmc_ros.bag.reader`) locates the same fields with it. No ROS import: plain
``struct``.

Layout rules (OMG CDR, as ROS 2's Fast CDR uses them): a 4-byte encapsulation
header ``00 01 00 00``; primitives aligned to their size relative to the end of
that header; strings as ``uint32`` length (including the NUL), bytes, NUL;
sequences as ``uint32`` count then the elements. Padding bytes are zeros. rclpy
leaves its padding uninitialised and sizes its buffer with the worst-case
padding (trailing bytes of garbage), so the tests compare content: rclpy reads
our bytes back to the same message and we read its bytes.
"""

from __future__ import annotations

import struct
from collections.abc import Sequence
from typing import Literal, overload

import numpy as np

from ..errors import CdrError
from .cdr_layout import (  # noqa: F401 (the writer and the caches are read by the tests through this module)
    _STAMP,
    _TWO_U32,
    _U32,
    HEADER,
    _decode_layouts,
    _encode_layouts,
    _fast_decode,
    _fast_decode_named,
    _fields_of,
    _FixedLayout,
    _learn,
    _Reader,
    _remember,
    _Writer,
    learn_encoding,
)

_NamedColumns = tuple[tuple[str, ...], int, int, tuple[float, ...], tuple[float, ...], tuple[float, ...]]
"""``(names, sec, nanosec, three double columns)`` of a JointState or of a JointTrajectory's point."""


def decode_stamp(data: bytes) -> tuple[int, int]:
    """``(sec, nanosec)`` of a message that starts with a ``std_msgs/Header``."""
    if len(data) >= 12 and data[1] == 1:
        return _STAMP.unpack_from(data, 4)  # right after the encapsulation header, aligned
    return _Reader(data).stamp()


def decode_string(data: bytes) -> str:
    """The text of a ``std_msgs/msg/String``."""
    r = _Reader(data)
    length = r.u32()
    return data[r.pos : r.pos + length].rstrip(b"\x00").decode("utf-8")


def float64_multi_array_offset(data: bytes) -> int:
    """``layout.data_offset`` of a ``Float64MultiArray`` (dimensions are refused)."""
    if len(data) >= 12 and data[1] == 1:
        dims, offset = _TWO_U32.unpack_from(data, 4)
        if dims == 0:
            return int(offset)
    return _Reader(data).multi_array_offset()


def encode_joint_state(
    sec: int, nanosec: int, names: Sequence[str], position: Sequence[float],
    velocity: Sequence[float], effort: Sequence[float], frame_id: str = "",
) -> bytes:
    """``sensor_msgs/msg/JointState``."""
    return _encode_joint_columns("js", sec, nanosec, names, position, velocity, effort, frame_id)


def _encode_joint_columns(
    kind: str, sec: int, nanosec: int, names: Sequence[str], first: Sequence[float],
    second: Sequence[float], third: Sequence[float], frame_id: str,
) -> bytes:
    """A header, the joint names and three double columns: a ``JointState`` (``kind`` "js":
    position, velocity, effort) or a one-point ``JointTrajectory`` ("jt": the point's positions,
    velocities and accelerations, inside a one-element point sequence after them come its empty
    effort and ``time_from_start = 0``). One ``pack`` once the shape has been written."""
    key = (kind, frame_id, *names, len(first), len(second), len(third))
    layout = _encode_layouts.get(key)
    if layout is not None:
        return layout.write((sec, nanosec), first, second, third)
    point = kind == "jt"
    w = _Writer()
    w.header_and_names(sec, nanosec, frame_id, names)
    if point:
        w.u32(1)  # one point
    for column in (first, second, third):
        w.doubles(column)
    if point:
        w.doubles(())  # the point's effort
        w.stamp(0, 0)  # time_from_start
    return learn_encoding(key, bytes(w.buf), _joint_trajectory_fields if point else _joint_state_fields)


def _joint_state_fields(data: bytes) -> list[tuple[int, str]]:
    return _fields_of(joint_state_spans(data), [(4, "iI")])


def decode_joint_state(data: bytes) -> tuple[int, int, tuple[float, ...], tuple[float, ...], tuple[float, ...]]:
    """``(sec, nanosec, position, velocity, effort)`` of a ``JointState``."""
    fast = _fast_decode("js", data)
    if fast is not None:
        (sec, nanosec), position, velocity, effort = fast
        return sec, nanosec, position, velocity, effort  # type: ignore[return-value]
    return decode_joint_state_named(data)[1:]


def decode_joint_state_named(data: bytes) -> _NamedColumns:
    """``(names, sec, nanosec, position, velocity, effort)`` of a ``JointState``.

    Raises
    ------
    CdrError
        If ``data`` is not a well-formed message (truncated, corrupt counts).
    """
    return _decode_joint_columns_named("js", data)


@overload
def _decode_joint_columns_named(kind: Literal["js"], data: bytes) -> _NamedColumns: ...
@overload
def _decode_joint_columns_named(kind: Literal["jt"], data: bytes) -> _NamedColumns | None: ...
def _decode_joint_columns_named(kind: str, data: bytes) -> _NamedColumns | None:
    """``(names, sec, nanosec, first, second, third)``: the three double columns of a
    ``JointState`` (``kind`` "js") or of a ``JointTrajectory``'s first point ("jt"; None
    without points), as :func:`_encode_joint_columns` lays them out. The general reader
    remembers the shape of what it reads (a trajectory's only when it has one point)."""
    fast = _fast_decode_named(kind, data)
    if fast is not None:
        names, ((sec, nanosec), first, second, third) = fast
        return names, sec, nanosec, first, second, third  # type: ignore[return-value]
    point = kind == "jt"
    r = _Reader(data)
    try:
        sec, nanosec = r.stamp()
        r.skip_string()  # frame_id
        names = r.strings()
        if point and r.u32() == 0:
            return None
        decoded = names, sec, nanosec, r.doubles(), r.doubles(), r.doubles()
    except struct.error as exc:
        raise CdrError(f"truncated {'JointTrajectory' if point else 'JointState'} ({exc})") from None
    if not point:
        _learn(kind, data, _joint_state_fields, names)
    elif _joint_trajectory_is_one_point(data):
        _learn(kind, data, _joint_trajectory_fields, names)
    return decoded


def encode_joint_trajectory(
    sec: int, nanosec: int, names: Sequence[str], positions: Sequence[float],
    velocities: Sequence[float], accelerations: Sequence[float], frame_id: str = "",
) -> bytes:
    """``trajectory_msgs/msg/JointTrajectory`` with one point at ``time_from_start = 0``."""
    return _encode_joint_columns("jt", sec, nanosec, names, positions, velocities, accelerations, frame_id)


def encode_joint_trajectories(
    stamps: Sequence[tuple[int, int]], names: Sequence[str], positions: np.ndarray,
    velocities: np.ndarray, accelerations: np.ndarray, frame_id: str = "",
) -> list[bytes]:
    """:func:`encode_joint_trajectory` of many references at once (rows of the arrays).

    The same bytes, written with numpy into copies of the first message: the
    trajectory encodes its references a window at a time instead of one per
    control step (test/test_cdr.py checks them against the one-by-one encoder).
    """
    count = len(stamps)
    if count == 0:
        return []
    columns = [np.ascontiguousarray(a, dtype="<f8").reshape(count, -1) for a in (positions, velocities, accelerations)]
    position, velocity, acceleration = (c[0].tolist() for c in columns)
    first = encode_joint_trajectory(stamps[0][0], stamps[0][1], names, position, velocity, acceleration,
                                    frame_id=frame_id)
    size = len(first)
    block = np.tile(np.frombuffer(first, dtype=np.uint8), (count, 1))
    stamp = np.array(stamps, dtype=np.int64)
    block[:, 4:8] = stamp[:, 0].astype("<i4").view(np.uint8).reshape(count, 4)
    block[:, 8:12] = stamp[:, 1].astype("<u4").view(np.uint8).reshape(count, 4)
    for (start, width), column in zip(joint_trajectory_spans(first).values(), columns):
        block[:, start:start + 8 * width] = column.view(np.uint8).reshape(count, 8 * width)
    data = block.tobytes()
    return [data[k:k + size] for k in range(0, count * size, size)]


def _joint_trajectory_fields(data: bytes) -> list[tuple[int, str]]:
    return _fields_of(joint_trajectory_spans(data), [(4, "iI")])


def decode_joint_trajectory(
    data: bytes,
) -> tuple[int, int, tuple[float, ...], tuple[float, ...], tuple[float, ...]] | None:
    """``(sec, nanosec, positions, velocities, accelerations)`` of the first point, or None."""
    fast = _fast_decode("jt", data)
    if fast is not None:
        (sec, nanosec), positions, velocities, accelerations = fast
        return sec, nanosec, positions, velocities, accelerations  # type: ignore[return-value]
    named = decode_joint_trajectory_named(data)
    return None if named is None else named[1:]


def decode_joint_trajectory_named(data: bytes) -> _NamedColumns | None:
    """``(names, sec, nanosec, positions, velocities, accelerations)`` of the first point,
    or None without points (the one-point reference stream's fast path).

    Raises
    ------
    CdrError
        If ``data`` is not a well-formed message.
    """
    return _decode_joint_columns_named("jt", data)


def _joint_trajectory_is_one_point(data: bytes) -> bool:
    r = _Reader(data)
    r.header_and_names()
    return r.u32() == 1


def decode_joint_trajectory_points(
    data: bytes,
) -> tuple[int, int, tuple[str, ...], list[tuple[tuple[float, ...], tuple[float, ...], tuple[float, ...], int, int]]]:
    """Every point of a ``JointTrajectory``: ``(sec, nanosec, names, points)``.

    Each point is ``(positions, velocities, accelerations, tfs_sec, tfs_nanosec)``
    (``time_from_start``; the point's effort is skipped).

    Raises
    ------
    CdrError
        If ``data`` is not a well-formed message.
    """
    r = _Reader(data)
    try:
        sec, nanosec = r.stamp()
        r.skip_string()  # frame_id
        names = r.strings()
        count = r.u32()
        if count > len(data):
            raise CdrError("JointTrajectory point count longer than its message")
        points = []
        for _ in range(count):
            positions, velocities, accelerations = r.doubles(), r.doubles(), r.doubles()
            r.doubles()  # effort
            tfs_sec, tfs_nanosec = r.stamp()
            points.append((positions, velocities, accelerations, tfs_sec, tfs_nanosec))
    except struct.error as exc:
        raise CdrError(f"truncated JointTrajectory ({exc})") from None
    return sec, nanosec, names, points


def encode_float64_multi_array(data: Sequence[float], data_offset: int = 0) -> bytes:
    """``std_msgs/msg/Float64MultiArray`` without layout dimensions."""
    key = ("fa", len(data))
    layout = _encode_layouts.get(key)
    if layout is not None:
        return layout.write((data_offset,), data)
    w = _Writer()
    w.u32(0)  # layout.dim
    w.u32(data_offset)
    w.doubles(data)
    return learn_encoding(key, bytes(w.buf), _float64_multi_array_fields)


def _float64_multi_array_fields(data: bytes) -> list[tuple[int, str]]:
    return _fields_of(float64_multi_array_spans(data), [(8, "I")])  # layout.data_offset


def decode_float64_multi_array(data: bytes) -> tuple[int, tuple[float, ...]]:
    """``(layout.data_offset, data)``; layouts with dimensions are refused."""
    fast = _fast_decode("fa", data)
    if fast is not None:
        (offset,), values = fast
        return offset, values  # type: ignore[return-value]
    r = _Reader(data)
    offset = r.multi_array_offset()
    decoded = offset, r.doubles()
    _learn("fa", data, _float64_multi_array_fields)
    return decoded


def encode_clock(sec: int, nanosec: int) -> bytes:
    """``rosgraph_msgs/msg/Clock``."""
    return HEADER + _STAMP.pack(sec, nanosec)


def encode_point_stamped(sec: int, nanosec: int, x: float, y: float, z: float = 0.0,
                         frame_id: str = "") -> bytes:
    """``geometry_msgs/msg/PointStamped``."""
    key = ("ps", frame_id)
    layout = _encode_layouts.get(key)
    if layout is not None:
        return layout.write((sec, nanosec), (x, y, z))
    w = _Writer()
    w.stamp(sec, nanosec)
    w.string(frame_id)
    w.align(8)
    start = len(w.buf)
    w.buf += struct.pack("<3d", x, y, z)
    return learn_encoding(key, bytes(w.buf), lambda _: [(4, "iI"), (start, "3d")])


# Byte spans (offset of the first double, count) for bulk decoding of many messages
# that share one layout (pdsmc_ros.bag.reader decodes a whole bag with numpy).
def joint_state_spans(data: bytes) -> dict[str, tuple[int, int]]:
    """Spans of ``position``, ``velocity`` and ``effort`` in a ``JointState``."""
    r = _Reader(data)
    r.header_and_names()
    return {field: r.double_span() for field in ("position", "velocity", "effort")}


def joint_trajectory_spans(data: bytes) -> dict[str, tuple[int, int]]:
    """Spans of the first point's ``positions``, ``velocities`` and ``accelerations``."""
    r = _Reader(data)
    r.header_and_names()
    r.u32()  # number of points (a reference has one)
    return {field: r.double_span() for field in ("positions", "velocities", "accelerations")}


def float64_multi_array_spans(data: bytes) -> dict[str, tuple[int, int]]:
    """Span of ``data`` in a ``Float64MultiArray`` without dimensions."""
    r = _Reader(data)
    r.multi_array_offset()
    return {"data": r.double_span()}
