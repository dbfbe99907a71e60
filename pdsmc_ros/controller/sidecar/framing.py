"""The one framing of the controller's sidecar processes: length-prefixed pickles over pipes.

A message is its pickle preceded by its length (:data:`FRAME`, 4 bytes little-endian). The
loop's process reads and writes its pipes non-blocking (:class:`FrameReader`,
:class:`FrameWriter`: the loop never waits for a child); a child reads its input blocking
(:meth:`FrameReader.read_blocking`) and writes whole frames (:func:`write_all`). The goal
process and the gain check both speak it. ROS-free.
"""

from __future__ import annotations

import contextlib
import fcntl
import os
import pickle
import struct
import threading

FRAME = struct.Struct("<I")  # a message's length before it
PIPE_SIZE = 1 << 20  # bytes: a 5,000-point goal in one pipe's buffer (Linux: fs.pipe-max-size, 1 MiB by default)
READ_CHUNK = 1 << 20
STATE_BACKLOG = 1 << 16  # bytes: a droppable message is dropped while this much waits to be written


def frame(message: object) -> bytes:
    """``message`` as one frame: its length, then its pickle.

    Raises
    ------
    pickle.PicklingError, AttributeError, TypeError
        ``message`` cannot be pickled (a class defined where a child cannot import it).
    """
    data = pickle.dumps(message, protocol=pickle.HIGHEST_PROTOCOL)
    return FRAME.pack(len(data)) + data


class FrameReader:
    """Length-prefixed pickles from a file descriptor (non-blocking in the loop's process)."""

    def __init__(self, fd: int) -> None:
        self.fd = fd
        self.buffer = bytearray()
        self.closed = False

    def read(self) -> list[object]:
        """Every complete message waiting now (a non-blocking descriptor: never waits)."""
        while True:
            try:
                chunk = os.read(self.fd, READ_CHUNK)
            except BlockingIOError:
                break
            except OSError:
                self.closed = True
                break
            if not chunk:
                self.closed = True
                break
            self.buffer += chunk
            if len(chunk) < READ_CHUNK:
                break
        return self._messages()

    def read_blocking(self) -> list[object]:
        """At least one message, or [] at the end of the input (a blocking descriptor)."""
        while not self.closed:
            messages = self._messages()
            if messages:
                return messages
            try:
                chunk = os.read(self.fd, READ_CHUNK)
            except OSError:
                chunk = b""
            if not chunk:
                self.closed = True
            self.buffer += chunk
        return self._messages()

    def _messages(self) -> list[object]:
        messages: list[object] = []
        buffer, start = self.buffer, 0
        while len(buffer) - start >= FRAME.size:
            (size,) = FRAME.unpack_from(buffer, start)
            end = start + FRAME.size + size
            if len(buffer) < end:
                break
            messages.append(pickle.loads(memoryview(buffer)[start + FRAME.size:end]))
            start = end
        if start:
            del buffer[:start]
        return messages


class FrameWriter:
    """Length-prefixed pickles to a non-blocking file descriptor: what does not fit waits for :meth:`flush`."""

    def __init__(self, fd: int) -> None:
        self.fd = fd
        self.pending = bytearray()
        self.closed = False
        # the loop's thread, the executor's (an activation, a forwarded trajectory): one frame at a time
        self.lock = threading.Lock()

    def send(self, message: object, *, droppable: bool = False) -> None:
        """Queue ``message`` and write what the pipe takes; a ``droppable`` one is dropped while a
        backlog waits (the child is slow: the next state message says the same, newer)."""
        if self.closed or (droppable and len(self.pending) > STATE_BACKLOG):
            return
        data = frame(message)
        with self.lock:
            self.pending += data
            self._flush()

    def flush(self) -> None:
        with self.lock:
            self._flush()

    def _flush(self) -> None:
        while self.pending and not self.closed:
            try:
                written = os.write(self.fd, self.pending)
            except BlockingIOError:
                return
            except OSError:
                self.closed = True
                return
            del self.pending[:written]


def write_all(fd: int, data: bytes) -> None:
    """Write all of ``data`` to a blocking descriptor (a child's output)."""
    view = memoryview(data)
    while view:
        written = os.write(fd, view)
        view = view[written:]


def grow(fd: int) -> None:
    """The pipe ``fd`` sized :data:`PIPE_SIZE` (where the system allows it)."""
    with contextlib.suppress(OSError, AttributeError):
        fcntl.fcntl(fd, fcntl.F_SETPIPE_SZ, PIPE_SIZE)
