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
from collections.abc import Callable, Sequence
from operator import itemgetter

import numpy as np

from ..errors import CdrError

HEADER = b"\x00\x01\x00\x00"
_U32 = struct.Struct("<I")
_STAMP = struct.Struct("<iI")
_TWO_U32 = struct.Struct("<II")


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

    def header_and_names(self, sec: int, nanosec: int, frame_id: str, names: Sequence[str]) -> None:
        """A ``std_msgs/Header`` followed by a string sequence (joint names)."""
        self.stamp(sec, nanosec)
        self.string(frame_id)
        self.strings(names)


class _Reader:
    """Sequential CDR reader over one serialized message."""

    __slots__ = ("data", "pos")

    def __init__(self, data: bytes) -> None:
        if len(data) < 4 or data[1] != 1:
            raise CdrError("not a little-endian CDR message")
        self.data = data
        self.pos = 4

    def align(self, size: int) -> None:
        self.pos += -(self.pos - 4) % size

    def u32(self) -> int:
        self.align(4)
        try:
            (value,) = _U32.unpack_from(self.data, self.pos)
        except struct.error:
            raise CdrError("truncated CDR message") from None
        self.pos += 4
        return int(value)

    def stamp(self) -> tuple[int, int]:
        self.align(4)
        try:
            sec, nanosec = _STAMP.unpack_from(self.data, self.pos)
        except struct.error:
            raise CdrError("truncated CDR header") from None
        self.pos += 8
        return sec, nanosec

    def skip_string(self) -> None:
        length = self.u32()
        self.pos += length

    def skip_strings(self) -> None:
        for _ in range(self.u32()):
            self.skip_string()

    def string(self) -> str:
        length = self.u32()
        start = self.pos
        self.pos += length
        if self.pos > len(self.data):
            raise CdrError("truncated CDR string")
        return self.data[start:self.pos].rstrip(b"\x00").decode("utf-8", errors="replace")

    def strings(self) -> tuple[str, ...]:
        count = self.u32()
        if count > len(self.data):  # each string takes at least 4 bytes: a corrupt count
            raise CdrError("CDR string sequence longer than its message")
        return tuple(self.string() for _ in range(count))

    def double_span(self) -> tuple[int, int]:
        """``(byte offset of the elements, count)`` of a double sequence; skips it."""
        count = self.u32()
        if count:
            self.align(8)
        start = self.pos
        self.pos += 8 * count
        if self.pos > len(self.data):
            raise CdrError("truncated CDR double sequence")
        return start, count

    def doubles(self) -> tuple[float, ...]:
        start, count = self.double_span()
        return struct.unpack_from(f"<{count}d", self.data, start) if count else ()

    def header_and_names(self) -> tuple[int, int]:
        """Read a ``std_msgs/Header`` and a string sequence; returns the stamp."""
        stamp = self.stamp()
        self.skip_string()  # frame_id
        self.skip_strings()  # joint names
        return stamp

    def multi_array_offset(self) -> int:
        """``layout.data_offset`` of a ``Float64MultiArray``; layouts with dimensions are refused."""
        if self.u32():
            raise CdrError("effort messages with layout dimensions are not produced by pdsmc_ros")
        return self.u32()


class _FixedLayout:
    """One message shape as a single ``struct``: constant bytes around fixed-size fields.

    Learned from one encoded message and the offsets of its variable fields (the
    stamp, ``layout.data_offset``, the double sequences). Every other byte -- string
    lengths and texts, sequence counts, padding -- decides where those fields lie,
    so a message of the same length whose other bytes are equal has them at the
    same offsets: it is read with one ``unpack`` and written with one ``pack``
    (a few microseconds instead of a field-by-field walk; the loop's messages all
    have one shape per run).
    """

    __slots__ = ("size", "struct", "consts", "const_at", "groups", "write", "names")

    def __init__(self, data: bytes, fields: Sequence[tuple[int, str]]) -> None:
        fmt, consts, const_idx, groups = "<", [], [], []
        pos = index = 0
        for offset, code in fields:  # ascending offsets; code: "iI", "I", "3d", ...
            fmt += f"{offset - pos}s{code}"
            consts.append(data[pos:offset])
            const_idx.append(index)
            width = len(struct.unpack_from("<" + code, data, offset))
            groups.append(slice(index + 1, index + 1 + width))
            index += 1 + width
            pos = offset + struct.calcsize("<" + code)
        fmt += f"{len(data) - pos}s"
        consts.append(data[pos:])
        const_idx.append(index)
        self.size = len(data)
        self.struct = struct.Struct(fmt)
        self.consts = tuple(consts)
        # C-level getters (itemgetter with several keys returns a tuple): about 2.5 us for a
        # JointState read, against 5.6 us with a Python loop over the groups
        getter = itemgetter(*const_idx)
        self.const_at = getter if len(const_idx) > 1 else (lambda values: (values[const_idx[0]],))
        groups_of = itemgetter(*groups)
        self.groups = groups_of if len(groups) > 1 else (lambda values: (values[groups[0]],))
        self.write = _writer(self.struct.pack, self.consts)
        self.names: tuple[str, ...] | None = None  # joint names, constant bytes of the shape

    def read(self, data: bytes) -> tuple[tuple[float | int, ...], ...] | None:
        """The variable fields of ``data`` (a tuple each), or None if it has another shape."""
        if len(data) != self.size:
            return None
        values = self.struct.unpack(data)
        if self.const_at(values) != self.consts:
            return None
        return self.groups(values)


def _writer(pack: Callable[..., bytes], consts: tuple[bytes, ...]) -> Callable[..., bytes]:
    """``write(*fields)`` of a layout: its constant bytes around the given field values.

    Spelled out for the loop's shapes (one to four variable fields: 1.9 us for a
    JointState against 4.2 us building the argument list in a loop); any other
    count takes the loop.
    """
    if len(consts) == 2:
        c0, c1 = consts
        return lambda f0: pack(c0, *f0, c1)
    if len(consts) == 3:
        c0, c1, c2 = consts
        return lambda f0, f1: pack(c0, *f0, c1, *f1, c2)
    if len(consts) == 4:
        c0, c1, c2, c3 = consts
        return lambda f0, f1, f2: pack(c0, *f0, c1, *f1, c2, *f2, c3)
    if len(consts) == 5:
        c0, c1, c2, c3, c4 = consts
        return lambda f0, f1, f2, f3: pack(c0, *f0, c1, *f1, c2, *f2, c3, *f3, c4)

    def write(*fields: Sequence[float | int]) -> bytes:
        args: list[object] = []
        for const, values in zip(consts, fields):
            args.append(const)
            args.extend(values)
        args.append(consts[-1])
        return pack(*args)

    return write


_LAYOUT_CACHE_SIZE = 32  # shapes kept per message kind (a run has one or two)
_encode_layouts: dict[tuple[object, ...], _FixedLayout] = {}
_decode_layouts: dict[tuple[str, int], _FixedLayout] = {}


def _remember(cache: dict, key: object, layout: _FixedLayout) -> None:  # type: ignore[type-arg]
    if len(cache) >= _LAYOUT_CACHE_SIZE:
        cache.clear()  # e.g. a fuzzer's endless shapes: start over rather than grow
    cache[key] = layout


def _fields_of(spans: dict[str, tuple[int, int]], head: Sequence[tuple[int, str]]) -> list[tuple[int, str]]:
    return [*head, *((start, f"{count}d") for start, count in spans.values())]


def _fast_decode(kind: str, data: bytes) -> tuple[tuple[float | int, ...], ...] | None:
    layout = _decode_layouts.get((kind, len(data)))
    return None if layout is None else layout.read(data)


def _learn(kind: str, data: bytes, fields: Callable[[bytes], list[tuple[int, str]]],
           names: tuple[str, ...] | None = None) -> None:
    """Remember the shape of a message that the general decoder has just read."""
    layout = _FixedLayout(data, fields(data))
    layout.names = names
    _remember(_decode_layouts, (kind, len(data)), layout)


def _fast_decode_named(kind: str, data: bytes) -> tuple[tuple[str, ...], tuple[tuple[float | int, ...], ...]] | None:
    """:func:`_fast_decode` with the joint names of the shape (the same tuple object for
    every message of one shape, so name matching can be cached per name list)."""
    layout = _decode_layouts.get((kind, len(data)))
    if layout is None or layout.names is None:
        return None
    fields = layout.read(data)
    return None if fields is None else (layout.names, fields)


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
    key = ("js", frame_id, *names, len(position), len(velocity), len(effort))
    layout = _encode_layouts.get(key)
    if layout is not None:
        return layout.write((sec, nanosec), position, velocity, effort)
    w = _Writer()
    w.header_and_names(sec, nanosec, frame_id, names)
    w.doubles(position)
    w.doubles(velocity)
    w.doubles(effort)
    data = bytes(w.buf)
    _remember(_encode_layouts, key, _FixedLayout(data, _joint_state_fields(data)))
    return data


def _joint_state_fields(data: bytes) -> list[tuple[int, str]]:
    return _fields_of(joint_state_spans(data), [(4, "iI")])


def decode_joint_state(data: bytes) -> tuple[int, int, tuple[float, ...], tuple[float, ...], tuple[float, ...]]:
    """``(sec, nanosec, position, velocity, effort)`` of a ``JointState``."""
    fast = _fast_decode("js", data)
    if fast is not None:
        (sec, nanosec), position, velocity, effort = fast
        return sec, nanosec, position, velocity, effort  # type: ignore[return-value]
    return decode_joint_state_named(data)[1:]


def decode_joint_state_named(
    data: bytes,
) -> tuple[tuple[str, ...], int, int, tuple[float, ...], tuple[float, ...], tuple[float, ...]]:
    """``(names, sec, nanosec, position, velocity, effort)`` of a ``JointState``.

    Raises
    ------
    CdrError
        If ``data`` is not a well-formed message (truncated, corrupt counts).
    """
    fast = _fast_decode_named("js", data)
    if fast is not None:
        names, ((sec, nanosec), position, velocity, effort) = fast
        return names, sec, nanosec, position, velocity, effort  # type: ignore[return-value]
    r = _Reader(data)
    try:
        sec, nanosec = r.stamp()
        r.skip_string()  # frame_id
        names = r.strings()
        decoded = names, sec, nanosec, r.doubles(), r.doubles(), r.doubles()
    except struct.error as exc:
        raise CdrError(f"truncated JointState ({exc})") from None
    _learn("js", data, _joint_state_fields, names)
    return decoded


def encode_joint_trajectory(
    sec: int, nanosec: int, names: Sequence[str], positions: Sequence[float],
    velocities: Sequence[float], accelerations: Sequence[float], frame_id: str = "",
) -> bytes:
    """``trajectory_msgs/msg/JointTrajectory`` with one point at ``time_from_start = 0``."""
    key = ("jt", frame_id, *names, len(positions), len(velocities), len(accelerations))
    layout = _encode_layouts.get(key)
    if layout is not None:
        return layout.write((sec, nanosec), positions, velocities, accelerations)
    w = _Writer()
    w.header_and_names(sec, nanosec, frame_id, names)
    w.u32(1)  # one point
    w.doubles(positions)
    w.doubles(velocities)
    w.doubles(accelerations)
    w.doubles(())  # effort
    w.stamp(0, 0)  # time_from_start
    data = bytes(w.buf)
    _remember(_encode_layouts, key, _FixedLayout(data, _joint_trajectory_fields(data)))
    return data


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


def decode_joint_trajectory_named(
    data: bytes,
) -> tuple[tuple[str, ...], int, int, tuple[float, ...], tuple[float, ...], tuple[float, ...]] | None:
    """``(names, sec, nanosec, positions, velocities, accelerations)`` of the first point,
    or None without points (the one-point reference stream's fast path).

    Raises
    ------
    CdrError
        If ``data`` is not a well-formed message.
    """
    fast = _fast_decode_named("jt", data)
    if fast is not None:
        names, ((sec, nanosec), positions, velocities, accelerations) = fast
        return names, sec, nanosec, positions, velocities, accelerations  # type: ignore[return-value]
    r = _Reader(data)
    try:
        sec, nanosec = r.stamp()
        r.skip_string()  # frame_id
        names = r.strings()
        if r.u32() == 0:
            return None
        decoded = names, sec, nanosec, r.doubles(), r.doubles(), r.doubles()
    except struct.error as exc:
        raise CdrError(f"truncated JointTrajectory ({exc})") from None
    if _joint_trajectory_is_one_point(data):
        _learn("jt", data, _joint_trajectory_fields, names)
    return decoded


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
    encoded = bytes(w.buf)
    _remember(_encode_layouts, key, _FixedLayout(encoded, _float64_multi_array_fields(encoded)))
    return encoded


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
    data = bytes(w.buf)
    _remember(_encode_layouts, key, _FixedLayout(data, [(4, "iI"), (start, "3d")]))
    return data


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
