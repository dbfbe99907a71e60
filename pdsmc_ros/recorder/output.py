"""What both recorders share: the bag they write, its periodic flush, and how a failed write ends
the recording."""

from __future__ import annotations

import threading
from pathlib import Path
from typing import Any

from rclpy.node import Node

from ..bag.writer import flush_chunk
from ..loop.lifecycle import EXIT_FAILURE

# topic -> (rclpy type, ROS type name, QoS)

FLUSH_PERIOD_S = 0.5
"""Seconds between flushes of the bag's pending chunk to disk."""


class BagOutput:
    """What both recorders share: the bag they write, its periodic flush, and how a failed write
    ends the recording (an error logged, exit status 1)."""

    node: Node
    path: Path
    lock: threading.Lock
    writer: Any
    exit_code: int
    done: bool

    def write_failed(self, exc: OSError) -> None:
        self.node.get_logger().error(f"write to {self.path} failed: {exc}")
        self.exit_code = EXIT_FAILURE
        self.done = True

    def flush(self) -> None:
        """Write the pending chunk to disk (reaches the OS: survives SIGKILL)."""
        try:
            with self.lock:
                flush_chunk(self.writer)
        except OSError as exc:
            self.write_failed(exc)
