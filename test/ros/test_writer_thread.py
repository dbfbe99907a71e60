"""The real-time command's writer thread (:class:`~pdsmc_ros.ros.publishers.WriterThread`): what a
plain rclpy subscription receives from it: the bytes as handed over, in order, the newest always
last. (That the loop no longer waits in the middleware is measured by ``bench/storm/``.)"""

from __future__ import annotations

import threading
import time

import pytest

rclpy = pytest.importorskip("rclpy")

from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.node import Node  # noqa: E402
from rclpy.qos import QoSProfile, ReliabilityPolicy  # noqa: E402
from rclpy.serialization import serialize_message  # noqa: E402
from std_msgs.msg import Float64MultiArray  # noqa: E402

from pdsmc_ros.ros.publishers import GuardedPublisher, WriterThread  # noqa: E402

TOPIC = "/writer_thread_test"
QOS = QoSProfile(depth=5000, reliability=ReliabilityPolicy.RELIABLE)



@pytest.fixture
def node(rclpy_node: Node) -> Node:
    return rclpy_node


def receive(node: Node, until_last: float, timeout: float = 20.0) -> list[list[float]]:
    """Messages on TOPIC until one whose first value is ``until_last``."""
    got: list[list[float]] = []
    node.create_subscription(Float64MultiArray, TOPIC, lambda m: got.append(list(m.data)), QOS)
    executor = SingleThreadedExecutor(context=node.context)
    executor.add_node(node)
    deadline = time.monotonic() + timeout
    while (not got or got[-1][0] != until_last) and time.monotonic() < deadline:
        executor.spin_once(timeout_sec=0.05)
    executor.remove_node(node)
    return got


def listen(node: Node, until_last: float) -> tuple[threading.Thread, list[list[list[float]]]]:
    """A thread receiving (:func:`receive`) into the list returned, started."""
    results: list[list[list[float]]] = []
    listener = threading.Thread(target=lambda: results.append(receive(node, until_last)))
    listener.start()
    return listener, results


def encoded(k: int) -> bytes:
    return serialize_message(Float64MultiArray(data=[float(k), 1.5, -2.25, 1e-9, 0.0, 3.0]))


def wait_matched(publisher, count: int = 1, timeout: float = 10.0) -> None:
    deadline = time.monotonic() + timeout
    while publisher.get_subscription_count() < count and time.monotonic() < deadline:
        time.sleep(0.01)
    assert publisher.get_subscription_count() >= count


def test_every_message_handed_over_paced_arrives_intact_in_order(node: Node) -> None:
    publisher = node.create_publisher(Float64MultiArray, TOPIC, QOS)
    writer = WriterThread(publisher, node)
    listener, results = listen(node, 199.0)
    wait_matched(publisher)
    for k in range(200):
        writer.write(encoded(k))
        assert writer.flush(5.0)  # paced: each written before the next
    listener.join(30.0)
    writer.close()
    got = results[0]
    assert [m[0] for m in got] == [float(k) for k in range(200)]
    assert all(m[1:] == [1.5, -2.25, 1e-9, 0.0, 3.0] for m in got)
    assert writer.written == 200 and writer.superseded == 0 and writer.failures == 0
    assert "200 messages (0 failed), 0 superseded" in writer.summary()


def test_a_burst_keeps_order_and_the_newest_is_written_last(node: Node) -> None:
    publisher = node.create_publisher(Float64MultiArray, TOPIC, QOS)
    writer = WriterThread(publisher, node)
    listener, results = listen(node, 999.0)
    wait_matched(publisher)
    for k in range(1000):  # faster than the thread writes: older ones are superseded
        writer.write(encoded(k))
    assert writer.flush(10.0)
    listener.join(30.0)
    writer.close()
    order = [m[0] for m in results[0]]
    assert order[-1] == 999.0
    assert order == sorted(order) and len(set(order)) == len(order)
    assert writer.written + writer.superseded == 1000
    assert writer.written == len(order)


def test_guarded_publisher_routes_bytes_through_its_writer(node: Node) -> None:
    guarded = GuardedPublisher(node.create_publisher(Float64MultiArray, TOPIC, QOS), node, writer_thread=True)
    assert guarded.writer is not None
    listener, results = listen(node, 7.0)
    wait_matched(guarded.publisher)
    assert guarded.publish(encoded(7))
    assert guarded.writer.flush(5.0)
    listener.join(30.0)
    guarded.writer.close()
    assert results[0][-1][0] == 7.0 and guarded.writer.written == 1


def test_after_close_a_message_is_still_written(node: Node) -> None:
    """A zero command handed over after the thread ended is written from the caller's thread."""
    guarded = GuardedPublisher(node.create_publisher(Float64MultiArray, TOPIC, QOS), node, writer_thread=True)
    writer = guarded.writer
    assert writer is not None
    listener, results = listen(node, 5.0)
    wait_matched(guarded.publisher)
    writer.close()
    assert not writer.write(encoded(5))  # refused by the ended thread ...
    assert guarded.publish(encoded(5))  # ... so the publisher writes it itself
    listener.join(30.0)
    assert results[0][-1][0] == 5.0 and writer.written == 0
