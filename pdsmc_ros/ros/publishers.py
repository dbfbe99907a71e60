"""What the nodes publish: guarded publishers (a failed publish is logged, never fatal), the
middleware's writes of a real-time loop's command in a thread of their own, and rows in batches."""

from __future__ import annotations

import threading
import time
from collections.abc import Sequence
from typing import Any

import numpy as np
from rclpy.node import Node
from rclpy.serialization import serialize_message
from std_msgs.msg import Float64MultiArray, MultiArrayDimension

from .. import rclpy_internals as _rclpy_impl
from . import intra
from .topics import STREAM_QOS

RCLError = _rclpy_impl.RCLError


DELAYS_KEPT = 1 << 16  # the hand-off-to-written delays kept for the summary (the latest 65 s at 1 kHz)


class WriterThread:
    """The middleware's writes of one publisher's serialized messages, in a thread of their own.

    A write into Fast DDS takes its writer's lock, which Fast DDS's sending thread holds while it
    sends to every matched reader: in a storm of clients connecting (``bench/storm/``) the
    loop's effort command waited 0.7-13 ms there, the interpreter lock held all along (rclpy's
    raw publish keeps it). ros2_control's answer is realtime_tools' ``RealtimePublisher``: the
    loop hands the message over and a thread of its own publishes it. Here the loop's
    :meth:`write` stores the bytes in a one-message slot and wakes the thread, which calls
    rcl's publish with the interpreter lock released
    (:class:`~pdsmc_ros.rclpy_internals.SerializedPublish`), so
    neither the loop nor the process's other Python waits for the middleware.

    Where realtime_tools keeps the older message while its thread is busy, the newer one wins
    here: a command superseded before it was written is dropped (:attr:`superseded`), and the
    newest torque is the next on the wire. Messages are written in the order handed over, so a
    zero command handed over last is the last written. The thread is one of the process's
    others (raised to ``SCHED_FIFO`` 1 with them in real time: :func:`~pdsmc_ros.loop.realtime.raise_helpers`).
    """

    def __init__(self, publisher: Any, node: Node) -> None:
        self._publish = _rclpy_impl.SerializedPublish(publisher)  # OSError where rcl cannot be called
        self.node = node
        self.topic = publisher.topic_name
        self._cond = threading.Condition()
        self._pending: tuple[bytes, float] | None = None
        self._busy = False
        self._closing = False
        self.written = 0
        self.superseded = 0
        self.failures = 0
        self._delays = np.zeros(DELAYS_KEPT)
        self.delay_max = 0.0
        self._thread = threading.Thread(target=self._run, name="command writer", daemon=True)
        self._thread.start()

    def write(self, data: bytes) -> bool:
        """The loop's side: ``data`` is the next message to write (replacing one not yet written).
        False once the thread has ended (closed, or an error it logged): the caller writes it."""
        with self._cond:
            if self._closing or not self._thread.is_alive():
                return False
            if self._pending is not None:
                self.superseded += 1
            self._pending = (bytes(data), time.perf_counter())
            self._cond.notify()
            return True

    def _run(self) -> None:
        try:
            self._write_until_closed()
        except BaseException as exc:  # noqa: BLE001 - logged; write() then publishes from the caller's thread
            self.node.get_logger().error(f"{self.topic}: its writer thread ended ({exc!r}); written by the caller")
            raise

    def _write_until_closed(self) -> None:
        while True:
            with self._cond:
                while self._pending is None and not self._closing:
                    self._cond.wait()
                if self._pending is None:
                    return
                (data, handed), self._pending = self._pending, None
                self._busy = True
            failed, why = self._publish(data)
            delay = time.perf_counter() - handed
            with self._cond:
                self._busy = False
                self._delays[self.written % DELAYS_KEPT] = delay
                self.written += 1
                self.delay_max = max(self.delay_max, delay)
                if failed:
                    self.failures += 1
                self._cond.notify_all()
            if failed and (self.failures <= 5 or self.failures % 1000 == 0):
                self.node.get_logger().error(f"publish on {self.topic} failed ({self.failures} so far): {why}")

    def flush(self, timeout: float) -> bool:
        """Wait up to ``timeout`` s until every message handed over is written; whether they were."""
        with self._cond:
            return self._cond.wait_for(lambda: self._pending is None and not self._busy, timeout)

    def close(self, timeout: float = 1.0) -> None:
        """Write what is pending, then end the thread (before the publisher is destroyed)."""
        with self._cond:
            self._closing = True
            self._cond.notify_all()
        self._thread.join(timeout)

    def summary(self) -> str:
        """One line: messages written and superseded, and how long after the hand-over they were written."""
        with self._cond:
            kept = self._delays[:min(self.written, DELAYS_KEPT)] * 1e6
            written, superseded, failed, worst = self.written, self.superseded, self.failures, self.delay_max
        if not len(kept):
            return f"{self.topic}: nothing written"
        p50, p99, p999 = np.percentile(kept, [50, 99, 99.9])
        return (f"{self.topic} written by its own thread: {written} messages ({failed} failed), {superseded} "
                f"superseded by a newer one before written; hand-over to written p50 {p50:.0f} us, p99 {p99:.0f} us, "
                f"p99.9 {p999:.0f} us, max {1e6 * worst:.0f} us")


class GuardedPublisher:
    """A publisher whose failures (e.g. a dead reliable subscriber not yet dropped)
    are logged, throttled, and counted instead of killing the node."""

    def __init__(self, publisher: Any, node: Node, *, writer_thread: bool = False) -> None:
        self.publisher = publisher
        self.node = node
        self.failures = 0
        self._write_serialized = _rclpy_impl.raw_publisher(publisher)
        # serialized messages written by a thread of their own (the real-time loop's command)
        self.writer: WriterThread | None = None
        if writer_thread:
            try:
                self.writer = WriterThread(publisher, node)
            except OSError as exc:
                node.get_logger().warn(f"{publisher.topic_name}: written by the loop's thread ({exc})")
        # composed with --intra-process: local subscribers get the bytes directly (loop.intra)
        domain = intra.current()
        self._route = None if domain is None else domain.add_publisher(
            publisher, publisher.msg_type, publisher.qos_profile)

    def publish(self, msg: Any) -> bool:
        try:
            route = self._route
            if type(msg) is bytes:  # the loop's serialized messages: straight to rcl
                # over DDS unless only local subscribers take it; by the writer's thread while it runs
                if (route is None or route.deliver(msg)) and (self.writer is None or not self.writer.write(msg)):
                    self._write_serialized(msg)
            else:
                data = serialize_message(msg) if route is not None and route.queues else b""
                if route is None or route.deliver(data):
                    self.publisher.publish(msg)
            return True
        except RCLError as exc:
            self.failures += 1
            if self.failures <= 5 or self.failures % 1000 == 0:
                self.node.get_logger().error(
                    f"publish on {self.publisher.topic_name} failed ({self.failures} so far): {exc}")
            return False

    def get_subscription_count(self) -> int:
        """Matched subscribers: over DDS, plus those in this process on the intra-process path."""
        if self._route is None:
            return self.publisher.get_subscription_count()
        return self._route.refresh() + len(self._route.queues)

    def participants(self) -> int:
        """Matched subscribers that take part in the run: observers (best-effort readers, the
        live viewer) are not waited for, so one can never stand in for a recorder not yet matched."""
        from rclpy.qos import ReliabilityPolicy

        observers = sum(1 for info in self.node.get_subscriptions_info_by_topic(self.publisher.topic_name)
                        if info.qos_profile.reliability == ReliabilityPolicy.BEST_EFFORT)
        return self.get_subscription_count() - observers


class RowBatches:
    """Rows of floats published in batches as one ``rows x width`` Float64MultiArray (one
    publish costs about as much as a control law's whole tick)."""

    def __init__(self, node: Node, topic: str, labels: tuple[str, str], width: int, *, batch: int) -> None:
        self.pub = GuardedPublisher(node.create_publisher(Float64MultiArray, topic, STREAM_QOS), node)
        self.labels = labels
        self.width = width
        self.batch = batch
        self.rows: list[float] = []

    def add(self, row: Sequence[float]) -> None:
        self.rows += row
        if len(self.rows) >= self.width * self.batch:
            self.flush()

    def flush(self) -> None:
        """Publish the pending rows."""
        if not self.rows:
            return
        count = len(self.rows) // self.width
        msg = Float64MultiArray()
        msg.layout.dim = [MultiArrayDimension(label=self.labels[0], size=count, stride=count * self.width),
                          MultiArrayDimension(label=self.labels[1], size=self.width, stride=self.width)]
        msg.data = self.rows
        self.pub.publish(msg)
        self.rows = []
