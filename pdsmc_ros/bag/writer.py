"""Appending messages to a rosbags MCAP bag without its per-message overhead (ROS-free).

rosbags' ``Writer.write`` checks the connection against a list of dataclasses
and builds each MCAP message record in a ``BytesIO`` of its own: about 15 us a
message here, and the recorder writes three or more per control step.
:class:`MessageAppender` writes the very same bytes (one ``struct`` header and
the payload into the open chunk) and keeps the writer's bookkeeping (message
counts, start and end times, chunk index) exactly as ``Writer.write`` would,
so ``Writer.close`` finishes the bag unchanged. It is used only on an
uncompressed MCAP writer, the recorder's, and checked against rosbags' own
output byte for byte (test/test_bagwrite.py); any other writer gets ``Writer.write``.
"""

from __future__ import annotations

import struct
import zlib
from collections import defaultdict
from collections.abc import Sequence
from io import BytesIO
from itertools import chain
from pathlib import Path
from typing import Any, cast

from rosbags.rosbag2 import CompressionMode, StoragePlugin, Writer
from rosbags.rosbag2.storage_mcap import McapWriter, PendingChunk

from ..errors import BagError, CdrError, ConfigError
from .stamps import effort_step, header_step

# MCAP Message record: opcode, record length, channel id, sequence, log time, publish time
_MESSAGE = struct.Struct("<BQHIQQ")
_MESSAGE_FIELDS = _MESSAGE.size - 9  # the record length counts what follows opcode and length
_OPCODE_MESSAGE = 0x05
_CHUNK_LIMIT = 2**20  # rosbags closes a chunk beyond 1 MiB; so do we
# MCAP Chunk record up to its compression string: opcode, length, start, end, uncompressed size, crc
_CHUNK_HEAD = struct.Struct("<BQQQQI")
_OPCODE_CHUNK = 0x06
_OPCODE_MESSAGE_INDEX = 0x07


class MessageAppender:
    """``append(timestamp, data)`` writes one message of one connection of ``writer``.

    Parameters
    ----------
    writer : rosbags.rosbag2.Writer
        An open writer; the connection must be one of its own.
    connection : rosbags.interfaces.Connection
        The connection (topic) the messages belong to.
    """

    def __init__(self, writer: Writer, connection: Any) -> None:
        if writer.storage is None:
            raise ValueError("the bag is not open")
        if connection not in writer.connections:
            raise ValueError(f"connection {connection.topic!r} is not one of this bag's")
        self.writer = writer
        self.connection = connection
        self.fast = type(writer.storage) is McapWriter and writer.compression_mode in (
            CompressionMode.NONE, CompressionMode.FILE) and writer.storage.compression == ""

    def append(self, timestamp: int, data: bytes) -> None:
        """Write one serialized message at ``timestamp`` (ns), as ``Writer.write`` would."""
        self.append_many(timestamp, (data,))

    def append_many(self, timestamp: int, messages: Sequence[bytes]) -> None:
        """Write several serialized messages, all received at ``timestamp`` (ns), in order.

        The same bytes as :meth:`append` once per message, with the bookkeeping
        looked up once (the recorder takes its messages in batches).
        """
        if not messages:
            return
        writer = self.writer
        if not self.fast:
            for data in messages:
                writer.write(self.connection, timestamp, data)
            return
        storage = cast(McapWriter, writer.storage)
        cid = self.connection.id
        if timestamp < storage.message_start_time:
            storage.message_start_time = timestamp
        if timestamp > storage.message_end_time:
            storage.message_end_time = timestamp
        storage.channel_stats[cid] += len(messages)
        pack = _MESSAGE.pack
        chunk = storage.chunk
        bio = chunk.bio
        for data in messages:
            if timestamp < chunk.message_start_time:
                chunk.message_start_time = timestamp
            if timestamp > chunk.message_end_time:
                chunk.message_end_time = timestamp
            # looked up per message: a new chunk gets this connection's index only with a message
            chunk.msgs[cid].append((timestamp, bio.tell()))
            bio.write(pack(_OPCODE_MESSAGE, _MESSAGE_FIELDS + len(data), cid, 0, timestamp, timestamp))
            bio.write(data)
            if bio.tell() > _CHUNK_LIMIT:
                close_chunk(storage)
                chunk = storage.chunk
                bio = chunk.bio
        writer.counts[cid] += len(messages)
        if timestamp < writer.min_timestamp:
            writer.min_timestamp = timestamp
        if timestamp > writer.max_timestamp:
            writer.max_timestamp = timestamp

    def append_received(self, messages: Sequence[tuple[bytes, int, int]]) -> None:
        """Write several serialized messages ``(data, received ns, sent ns)``, in order.

        As rosbag2 records since Jazzy: the MCAP log time is when the message was received,
        the publish time when it was sent (0: the middleware gave none, the receive time stands
        in). For a recorder that takes foreign topics, each message with its own times.
        """
        if not messages:
            return
        writer = self.writer
        if not self.fast:
            for data, received, _sent in messages:
                writer.write(self.connection, received, data)
            return
        storage = cast(McapWriter, writer.storage)
        cid = self.connection.id
        pack = _MESSAGE.pack
        for data, received, sent in messages:
            chunk = storage.chunk
            storage.message_start_time = min(storage.message_start_time, received)
            storage.message_end_time = max(storage.message_end_time, received)
            chunk.message_start_time = min(chunk.message_start_time, received)
            chunk.message_end_time = max(chunk.message_end_time, received)
            chunk.msgs[cid].append((received, chunk.bio.tell()))
            chunk.bio.write(pack(_OPCODE_MESSAGE, _MESSAGE_FIELDS + len(data), cid, 0, received, sent or received))
            chunk.bio.write(data)
            if chunk.bio.tell() > _CHUNK_LIMIT:
                close_chunk(storage)
            writer.min_timestamp = min(writer.min_timestamp, received)
            writer.max_timestamp = max(writer.max_timestamp, received)
        storage.channel_stats[cid] += len(messages)
        writer.counts[cid] += len(messages)


def close_chunk(storage: McapWriter) -> None:
    """``storage.close_chunk()`` with each message index packed at once, and the chunk's CRC.

    rosbags writes a chunk's message index eight bytes per call, about 2 us a
    message: 3 ms for the half second of data the recorder flushes at a time,
    which made a real-time control period late. Here one ``struct`` call per
    connection. rosbags leaves the chunk's ``uncompressed_crc`` 0 (not computed);
    here it is the CRC-32 of the chunk's records, as rosbag2's MCAP writer and the
    MCAP spec have it, so a reader detects a corrupted chunk (bag/mcapscan.py). Apart
    from that field, the bytes are rosbags' (test/bag/test_writer.py).
    """
    pending = storage.chunk
    data = pending.bio.getvalue()
    compressed = storage.compressor(data)
    compression = storage.compression.encode()
    bio = storage.bio
    chunk_start = bio.tell()
    bio.write(_CHUNK_HEAD.pack(_OPCODE_CHUNK, 8 + 8 + 8 + 4 + 4 + len(compression) + 8 + len(compressed),
                               pending.message_start_time, pending.message_end_time, len(data),
                               zlib.crc32(data)))
    bio.write(struct.pack(f"<I{len(compression)}sQ", len(compression), compression, len(compressed)))
    bio.write(compressed)
    chunk_end = bio.tell()
    offsets = []
    for cid, msgs in pending.msgs.items():
        offsets.append((cid, bio.tell()))
        count = 2 * len(msgs)
        bio.write(struct.pack(f"<BQHI{count}Q", _OPCODE_MESSAGE_INDEX, 2 + 4 + 8 * count, cid, 8 * count,
                              *chain.from_iterable(msgs)))
    index = BytesIO()  # the chunk index record, kept for the summary as rosbags keeps it
    index.write(struct.pack("<QQQQI", pending.message_start_time, pending.message_end_time, chunk_start,
                            chunk_end - chunk_start, 10 * len(offsets)))
    for cid, offset in offsets:
        index.write(struct.pack("<HQ", cid, offset))
    index.write(struct.pack("<Q", bio.tell() - chunk_end))
    index.write(struct.pack(f"<I{len(compression)}s", len(compression), compression))
    index.write(struct.pack("<QQ", len(compressed), len(data)))
    storage.chunks.append(index)
    storage.chunk = PendingChunk(2**63 - 1, 0, BytesIO(), defaultdict(list))


def open_new_bag(output: str) -> Writer:
    """A rosbags MCAP writer open on a new bag directory ``output`` (its parent created).

    ConfigError (what is wrong with ``output``) if it is empty, already exists or its parent
    cannot be created; BagError if the bag cannot be opened.
    """
    if not output:
        raise ConfigError("the bag directory to write is required")
    path = Path(output)
    if path.exists():
        raise ConfigError(f"{output!r} already exists; choose a new bag directory")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ConfigError(f"cannot create {str(path.parent)!r}: {exc.strerror}") from None
    writer = Writer(path, version=9, storage_plugin=StoragePlugin.MCAP)
    try:
        writer.open()
    except OSError as exc:
        raise BagError(f"cannot open bag {output!r} for writing: {exc}") from None
    return writer


def flush_chunk(writer: Writer | None) -> None:
    """Close ``writer``'s open MCAP chunk (:func:`close_chunk`, if it holds a message) and flush
    the file: on disk, it survives the process being killed. Nothing for a closed writer or
    one without chunks; OSError if the write fails."""
    storage = getattr(writer, "storage", None)
    if storage is None or not hasattr(storage, "close_chunk"):
        return
    if storage.chunk.bio.tell():
        close_chunk(storage)
    storage.bio.flush()


class RunProgress:
    """How far a recorded run is: the newest control step seen on each stepped topic.

    Parameters
    ----------
    topics : sequence of str
        Topics with one message per control step.
    effort_topic : str
        The one among them whose step is ``layout.data_offset`` (the others': header stamps).
    last_step : int
        The run's last step: the run is complete when every topic has it.
    rate : float
        Control rate (Hz) of the stamps.
    """

    def __init__(self, topics: Sequence[str], effort_topic: str, last_step: int, rate: float) -> None:
        self.seen = dict.fromkeys(topics, -1)
        self.effort_topic = effort_topic
        self.last_step = last_step
        self.rate = rate

    def step_of(self, topic: str, data: bytes) -> int | None:
        """The control step of a message of this run, or None (recorded, not counted): an
        effort with layout dimensions is not this loop's, a step beyond the run is a rogue
        publisher's."""
        try:
            step = effort_step(data) if topic == self.effort_topic else header_step(data, self.rate)
        except CdrError:
            return None
        return step if step <= self.last_step else None

    def batch(self, topic: str, batch: Sequence[bytes]) -> bool:
        """A batch of a stepped topic's messages, in arrival order; whether the run is complete."""
        # a topic's steps arrive in order, so the last message normally holds the newest; if it
        # does not count, every message of the batch is looked at
        seen = self.seen[topic]
        step = self.step_of(topic, batch[-1])
        if step is None or step <= seen:
            step = max((k for k in (self.step_of(topic, data) for data in batch) if k is not None), default=None)
        if step is None or step <= seen:
            return False
        self.seen[topic] = step
        return step >= self.last_step and all(v >= self.last_step for v in self.seen.values())
