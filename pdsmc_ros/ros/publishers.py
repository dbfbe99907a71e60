"""What the nodes publish: guarded publishers (a failed publish is logged, never fatal) and rows
in batches."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy_impl
from rclpy.node import Node
from rclpy.serialization import serialize_message
from std_msgs.msg import Float64MultiArray, MultiArrayDimension

from ..loop import intra
from .topics import STREAM_QOS

RCLError = _rclpy_impl.RCLError


class GuardedPublisher:
    """A publisher whose failures (e.g. a dead reliable subscriber not yet dropped)
    are logged, throttled, and counted instead of killing the node."""

    def __init__(self, publisher: Any, node: Node) -> None:
        self.publisher = publisher
        self.node = node
        self.failures = 0
        self._handle = publisher.handle
        # composed with --intra-process: local subscribers get the bytes directly (loop.intra)
        domain = intra.current()
        self._route = None if domain is None else domain.add_publisher(
            publisher, publisher.msg_type, publisher.qos_profile)

    def publish(self, msg: Any) -> bool:
        try:
            route = self._route
            if type(msg) is bytes:  # the loop's serialized messages: straight to rcl
                if route is None or route.deliver(msg):
                    with self._handle:
                        self._handle.publish_raw(msg)
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
