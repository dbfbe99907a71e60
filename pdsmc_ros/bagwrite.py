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
from typing import Any

from rosbags.rosbag2 import Writer
from rosbags.rosbag2.storage_mcap import McapWriter
from rosbags.rosbag2.writer import CompressionMode

# MCAP Message record: opcode, record length, channel id, sequence, log time, publish time
_MESSAGE = struct.Struct("<BQHIQQ")
_MESSAGE_FIELDS = _MESSAGE.size - 9  # the record length counts what follows opcode and length
_OPCODE_MESSAGE = 0x05
_CHUNK_LIMIT = 2**20  # rosbags closes a chunk beyond 1 MiB; so do we


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
        writer = self.writer
        if not self.fast:
            writer.write(self.connection, timestamp, data)
            return
        storage = writer.storage
        cid = self.connection.id
        if timestamp < storage.message_start_time:
            storage.message_start_time = timestamp
        if timestamp > storage.message_end_time:
            storage.message_end_time = timestamp
        storage.channel_stats[cid] += 1
        chunk = storage.chunk
        if timestamp < chunk.message_start_time:
            chunk.message_start_time = timestamp
        if timestamp > chunk.message_end_time:
            chunk.message_end_time = timestamp
        bio = chunk.bio
        chunk.msgs[cid].append((timestamp, bio.tell()))
        bio.write(_MESSAGE.pack(_OPCODE_MESSAGE, _MESSAGE_FIELDS + len(data), cid, 0, timestamp, timestamp))
        bio.write(data)
        if bio.tell() > _CHUNK_LIMIT:
            storage.close_chunk()
        writer.counts[cid] += 1
        if timestamp < writer.min_timestamp:
            writer.min_timestamp = timestamp
        if timestamp > writer.max_timestamp:
            writer.max_timestamp = timestamp
