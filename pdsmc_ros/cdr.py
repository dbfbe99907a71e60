"""CDR (XCDR1, little endian) encoding of the three messages of the control loop.

The lockstep nodes publish and take serialized messages (``raw=True``): building
a ``JointState`` in Python and converting it to C costs more than the control
law. These functions write exactly the bytes rclpy's ``serialize_message`` writes
(tested), and read back the fields the nodes use. No ROS import: plain
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

from .errors import BagError

HEADER = b"\x00\x01\x00\x00"
_U32 = struct.Struct("<I")
_STAMP = struct.Struct("<iI")


class _Writer:
    """Append-only CDR writer (offsets relative to the end of the encapsulation header)."""

    __slots__ = ("buf",)

    def __init__(self) -> None:
        self.buf = bytearray(HEADER)

    def align(self, size: int) -> None:
        pad = -(len(self.buf) - 4) % size
        if pad:
            self.buf += b"\x00" * pad

    def u32(self, value: int) -> None:
        self.align(4)
        self.buf += _U32.pack(value)

    def stamp(self, sec: int, nanosec: int) -> None:
        self.align(4)
        self.buf += _STAMP.pack(sec, nanosec)

    def string(self, text: str) -> None:
        data = text.encode()
        self.u32(len(data) + 1)
        self.buf += data + b"\x00"

    def strings(self, texts: Sequence[str]) -> None:
        self.u32(len(texts))
        for text in texts:
            self.string(text)

    def doubles(self, values: Sequence[float]) -> None:
        self.u32(len(values))
        if values:
            self.align(8)
            self.buf += struct.pack(f"<{len(values)}d", *values)


class _Reader:
    """Sequential CDR reader over one serialized message."""

    __slots__ = ("data", "pos")

    def __init__(self, data: bytes) -> None:
        if len(data) < 4 or data[1] != 1:
            raise BagError("not a little-endian CDR message")
        self.data = data
        self.pos = 4

    def align(self, size: int) -> None:
        self.pos += -(self.pos - 4) % size

    def u32(self) -> int:
        self.align(4)
        (value,) = _U32.unpack_from(self.data, self.pos)
        self.pos += 4
        return value

    def stamp(self) -> tuple[int, int]:
        self.align(4)
        sec, nanosec = _STAMP.unpack_from(self.data, self.pos)
        self.pos += 8
        return sec, nanosec

    def skip_string(self) -> None:
        length = self.u32()
        self.pos += length

    def skip_strings(self) -> None:
        for _ in range(self.u32()):
            self.skip_string()

    def doubles(self) -> tuple[float, ...]:
        count = self.u32()
        if not count:
            return ()
        self.align(8)
        values = struct.unpack_from(f"<{count}d", self.data, self.pos)
        self.pos += 8 * count
        return values


def decode_stamp(data: bytes) -> tuple[int, int]:
    """``(sec, nanosec)`` of a message that starts with a ``std_msgs/Header``."""
    return _Reader(data).stamp()


def encode_joint_state(
    sec: int, nanosec: int, names: Sequence[str], position: Sequence[float],
    velocity: Sequence[float], effort: Sequence[float], frame_id: str = "",
) -> bytes:
    """``sensor_msgs/msg/JointState``."""
    w = _Writer()
    w.stamp(sec, nanosec)
    w.string(frame_id)
    w.strings(names)
    w.doubles(position)
    w.doubles(velocity)
    w.doubles(effort)
    return bytes(w.buf)


def decode_joint_state(data: bytes) -> tuple[int, int, tuple[float, ...], tuple[float, ...], tuple[float, ...]]:
    """``(sec, nanosec, position, velocity, effort)`` of a ``JointState``."""
    r = _Reader(data)
    sec, nanosec = r.stamp()
    r.skip_string()
    r.skip_strings()
    return sec, nanosec, r.doubles(), r.doubles(), r.doubles()


def encode_joint_trajectory(
    sec: int, nanosec: int, names: Sequence[str], positions: Sequence[float],
    velocities: Sequence[float], accelerations: Sequence[float], frame_id: str = "",
) -> bytes:
    """``trajectory_msgs/msg/JointTrajectory`` with one point at ``time_from_start = 0``."""
    w = _Writer()
    w.stamp(sec, nanosec)
    w.string(frame_id)
    w.strings(names)
    w.u32(1)  # one point
    w.doubles(positions)
    w.doubles(velocities)
    w.doubles(accelerations)
    w.doubles(())  # effort
    w.stamp(0, 0)  # time_from_start
    return bytes(w.buf)


def decode_joint_trajectory(
    data: bytes,
) -> tuple[int, int, tuple[float, ...], tuple[float, ...], tuple[float, ...]] | None:
    """``(sec, nanosec, positions, velocities, accelerations)`` of the first point, or None."""
    r = _Reader(data)
    sec, nanosec = r.stamp()
    r.skip_string()
    r.skip_strings()
    if r.u32() == 0:
        return None
    return sec, nanosec, r.doubles(), r.doubles(), r.doubles()


def encode_float64_multi_array(data: Sequence[float], data_offset: int = 0) -> bytes:
    """``std_msgs/msg/Float64MultiArray`` without layout dimensions."""
    w = _Writer()
    w.u32(0)  # layout.dim
    w.u32(data_offset)
    w.doubles(data)
    return bytes(w.buf)


def decode_float64_multi_array(data: bytes) -> tuple[int, tuple[float, ...]]:
    """``(layout.data_offset, data)``; layouts with dimensions are refused."""
    r = _Reader(data)
    if r.u32():
        raise BagError("effort messages with layout dimensions are not produced by pdsmc_ros")
    offset = r.u32()
    return offset, r.doubles()
