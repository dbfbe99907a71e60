"""CDR (XCDR1, little endian) primitives and the remembered fixed layouts of :mod:`.cdr`.

A general writer and reader, and a *fixed layout*: once a message of one shape
(the same names, the same array lengths) has been written or read, its bytes are
one ``struct`` format with constant runs between the fields, so every further
message of that shape is one ``pack`` or ``unpack`` -- the loop's messages all
share one shape per run.
"""

from __future__ import annotations

import struct
from collections.abc import Callable, Sequence
from operator import itemgetter

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


def learn_encoding(key: tuple[object, ...], data: bytes,
                   fields: Callable[[bytes], list[tuple[int, str]]]) -> bytes:
    """Remember the shape of a message the general writer has just written
    (under ``key``: its kind, names and lengths); returns ``data``."""
    _remember(_encode_layouts, key, _FixedLayout(data, fields(data)))
    return data
