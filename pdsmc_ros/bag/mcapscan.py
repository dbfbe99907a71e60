"""A minimal, fast reader of the MCAP files the recorder writes.

Walks the top-level records and the chunks (uncompressed, zstd or lz4) and
returns the raw message bytes of the requested topics. It needs no summary
section, so a file cut short (recorder killed) is read up to its last
complete record -- everything that reached the disk.

MCAP format: https://mcap.dev/spec (magic, then ``opcode u8, length u64,
body`` records; a Chunk holds Schema/Channel/Message records).
"""

from __future__ import annotations

import struct
import zlib
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path

from ..errors import BagError

MAGIC = b"\x89MCAP0\r\n"
OP_CHANNEL = 0x04
OP_MESSAGE = 0x05
OP_CHUNK = 0x06
OP_DATA_END = 0x0F
OP_FOOTER = 0x02


@dataclass
class ScanResult:
    """Messages by topic (raw CDR bytes, in file order) and how the file ended."""

    messages: dict[str, list[bytes]] = field(default_factory=dict)
    log_times: dict[str, list[int]] = field(default_factory=dict)
    complete: bool = False
    bytes_read: int = 0
    file_size: int = 0


def _string(buf: memoryview, off: int) -> tuple[str, int]:
    (n,) = struct.unpack_from("<I", buf, off)
    return bytes(buf[off + 4 : off + 4 + n]).decode("utf-8"), off + 4 + n


def _decompress(kind: str, data: bytes, size: int) -> bytes:
    if kind == "":
        return data
    if kind == "zstd":
        import zstandard

        return zstandard.ZstdDecompressor().decompress(data, max_output_size=size)
    if kind == "lz4":
        import lz4.frame

        return bytes(lz4.frame.decompress(data))
    raise BagError(f"unsupported MCAP chunk compression {kind!r}")


def scan(path: str | Path, topics: Iterable[str]) -> ScanResult:
    """Raw messages of ``topics`` from an MCAP file, tolerating a truncated tail."""
    path = Path(path)
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise BagError(f"cannot read {str(path)!r}: {exc.strerror}") from None
    if not data.startswith(MAGIC):
        raise BagError(f"{str(path)!r} is not an MCAP file")
    wanted = set(topics)
    result = ScanResult(messages={t: [] for t in wanted}, log_times={t: [] for t in wanted},
                        file_size=len(data))
    channels: dict[int, str] = {}
    view = memoryview(data)
    off = len(MAGIC)
    end = len(data)
    while off + 9 <= end:
        opcode = data[off]
        (length,) = struct.unpack_from("<Q", data, off + 1)
        body = off + 9
        if body + length > end:
            break  # truncated record: stop at the last complete one
        if opcode == OP_CHANNEL:
            _read_channel(view, body, channels)
        elif opcode == OP_MESSAGE:
            _read_message(view, body, body + length, channels, result)
        elif opcode == OP_CHUNK:
            (_start, _end, size, crc) = struct.unpack_from("<QQQI", data, body)
            p = body + 24 + 4
            kind, p = _string(view, p)
            (rec_len,) = struct.unpack_from("<Q", data, p)
            p += 8
            inner = _decompress(kind, bytes(view[p : p + rec_len]), size)
            if crc and zlib.crc32(inner) != crc:  # 0: the writer did not compute one (rosbags)
                raise BagError(f"{str(path)!r}: the chunk at byte {off} is corrupted (CRC-32 "
                               f"{zlib.crc32(inner):08x}, recorded {crc:08x}); its messages are not read")
            _walk(memoryview(inner), channels, result)
        elif opcode in (OP_DATA_END, OP_FOOTER):
            result.complete = True
            off = body + length
            break
        off = body + length
    result.bytes_read = off
    return result


def _read_channel(buf: memoryview, off: int, channels: dict[int, str]) -> None:
    (cid, _schema) = struct.unpack_from("<HH", buf, off)
    topic, _ = _string(buf, off + 4)
    channels[cid] = topic


def _read_message(buf: memoryview, off: int, stop: int, channels: dict[int, str], result: ScanResult) -> None:
    (cid, _seq, log_time, _pub) = struct.unpack_from("<HIQQ", buf, off)
    topic = channels.get(cid)
    if topic in result.messages:
        result.messages[topic].append(bytes(buf[off + 22 : stop]))
        result.log_times[topic].append(log_time)


def _walk(buf: memoryview, channels: dict[int, str], result: ScanResult) -> None:
    off = 0
    end = len(buf)
    while off + 9 <= end:
        opcode = buf[off]
        (length,) = struct.unpack_from("<Q", buf, off + 1)
        body = off + 9
        if opcode == OP_CHANNEL:
            _read_channel(buf, body, channels)
        elif opcode == OP_MESSAGE:
            _read_message(buf, body, body + length, channels, result)
        off = body + length
