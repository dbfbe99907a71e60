"""The subscriptions of the nodes' loops, taken as serialized CDR, and their hand-over to handlers."""

from __future__ import annotations

import math
import time
from collections import deque
from collections.abc import Callable, Sequence
from typing import Any

from rclpy.node import Node
from rclpy.qos import QoSProfile

from ..ros import intra
from ..ros.topics import LATEST_QOS, LOCKSTEP_QOS

MAX_BATCH_S = 0.05  # an observer lets its messages gather at most this long


class Inputs:
    """The subscriptions of a node's control loop, taken as serialized CDR.

    They live on a lean companion node (``<name>_io``: no parameter services,
    no rosout) that no executor sees; :func:`run_nodes` takes their messages
    with a hand-driven wait set and calls the handlers directly, while the
    executor serves the node's timers, parameters and ``/clock`` in between.
    That path sets the lockstep rate (bench/lockstep.py) and the real-time
    jitter. Handlers receive the serialized message (:mod:`pdsmc_ros.bag.cdr`).
    QoS: every sample in lockstep, the newest in real time, unless given.

    ``batch_s`` > 0 makes the inputs an observer's: once woken, the loop lets
    messages gather for ``batch_s`` before it takes them again, so a node off
    the loop's critical path (the recorder) wakes a few hundred times a second
    instead of once per message, and leaves the cores to the nodes that are
    on it. Its subscriptions must keep every sample (keep-all or deep queues),
    and its handlers receive the messages of a batch as one list, in order.
    """

    def __init__(self, node: Node, mode: str, *, batch_s: float = 0.0, suffix: str = "_io") -> None:
        if not 0.0 <= batch_s <= MAX_BATCH_S:
            raise ValueError(f"batch_s must be in [0, {MAX_BATCH_S}] s, got {batch_s!r}")
        self.node = node
        self.mode = mode
        self.batch_s = batch_s
        self.suffix = suffix  # of the companion node's name (one per Inputs of a node)
        self.io_node: Node | None = None
        self.hot: list[tuple[Any, Callable[[bytes], None]]] = []
        # composed with --intra-process: inputs published in this process (nodes.intra)
        self.local: list[tuple[deque, Callable[[bytes], None]]] = []

    def subscribe(self, msg_type: Any, topic: str, handler: Callable[[bytes], None],
                  qos: QoSProfile | None = None, *, with_receipt: bool = False) -> None:
        """Hand ``topic``'s messages to ``handler``. ``with_receipt`` (observers): each message of a
        batch comes as ``(data, (sent, received))``, the middleware's source and reception
        times (s, system clock; None on the intra-process path or when the middleware gives
        none), so the time a message is taken never stands in for the time it was sent."""
        if with_receipt:
            handler = WithReceipt(handler)
        if qos is None:
            qos = LOCKSTEP_QOS if self.mode == "lockstep" else LATEST_QOS
        domain = intra.current()
        if domain is None:
            self._subscribe_dds(msg_type, topic, handler, qos)
            return
        domain.add_subscription(
            self.node.resolve_topic_name(topic), msg_type, qos,
            local=lambda queue: self.local.append((queue, handler)),
            dds=lambda: self._subscribe_dds(msg_type, topic, handler, qos))

    def _subscribe_dds(self, msg_type: Any, topic: str, handler: Callable[[bytes], None],
                       qos: QoSProfile) -> None:
        if self.io_node is None:
            # no global arguments: the companion must not get use_sim_time (a /clock
            # subscription nobody serves); topics are resolved by the node itself
            self.io_node = Node(f"{self.node.get_name()}{self.suffix}", namespace=self.node.get_namespace(),
                                context=self.node.context, use_global_arguments=False,
                                start_parameter_services=False, enable_rosout=False)
        name = self.node.resolve_topic_name(topic)
        sub = self.io_node.create_subscription(msg_type, name, _taken_by_wait_set, qos, raw=True)
        self.hot.append((sub, handler))

    def destroy(self) -> None:
        if self.io_node is not None:
            self.io_node.destroy_node()
            self.io_node = None


Times = tuple[float | None, float | None]
"""A message's ``(sent, received)`` times from the middleware (s, system clock; None: unknown)."""


class WithReceipt:
    """An observer's handler that receives ``(data, (sent, received))`` pairs (see :meth:`Inputs.subscribe`)."""

    def __init__(self, handler: Callable[[list[tuple[bytes, Times]]], None]) -> None:
        self.handler = handler

    def __call__(self, batch: list[Any]) -> None:
        self.handler([item if type(item) is tuple else (item, (None, None)) for item in batch])


def _times(info: dict[str, Any]) -> Times:
    # a middleware that gives no time gives 0
    return ((info.get("source_timestamp") or 0) * 1e-9 or None, (info.get("received_timestamp") or 0) * 1e-9 or None)


def _taken_by_wait_set(_msg: bytes) -> None:  # pragma: no cover - never called
    """Callback of a lockstep input: its messages are taken by run_nodes' wait set."""


def take_all(inputs: Sequence[tuple[Any, Callable[[], Any], Callable[[bytes], None]]]) -> bool:
    """Hand every waiting message of ``inputs`` (``(handle, take, handler)``, ``take`` as
    :func:`~pdsmc_ros.rclpy_internals.take_raw` makes it) to its handler; whether there was any."""
    took = False
    for _, take, handler in inputs:
        while True:
            taken = take()
            if taken is None:
                break
            handler(taken[0])
            took = True
    return took


def take_local(inputs: Sequence[tuple[deque, Callable[[bytes], None]]]) -> bool:
    """:func:`take_all` for intra-process inputs: empty each queue into its handler."""
    took = False
    for queue, handler in inputs:
        while queue:
            handler(queue.popleft())
            took = True
    return took


BOUNDED_BATCH = 8  # real time: an observer's batch handed over while a tick is near


def take_batches(inputs: Sequence[tuple[Any, Callable[[], Any], Callable[[list[bytes]], None]]],
                  until: float = math.inf) -> bool:
    """Observers: each input's waiting messages to its handler as one list.

    Once ``time.perf_counter()`` reaches ``until`` (a real-time tick is near),
    at most ``BOUNDED_BATCH`` messages per input, and none after the first
    input that had some; the rest stay queued for the next pass.
    """
    took = False
    for _, take, handler in inputs:
        limit = BOUNDED_BATCH if time.perf_counter() >= until else -1
        batch: list[Any] = []
        receipt = type(handler) is WithReceipt
        while len(batch) != limit:
            taken = take()
            if taken is None:
                break
            batch.append((taken[0], _times(taken[1])) if receipt else taken[0])
        if batch:
            handler(batch)
            took = True
            if limit > 0:
                return took
    return took


def take_local_batches(inputs: Sequence[tuple[deque, Callable[[list[bytes]], None]]],
                        until: float = math.inf) -> bool:
    """:func:`take_batches` for intra-process inputs."""
    took = False
    for queue, handler in inputs:
        count = len(queue)
        if not count:
            continue
        bounded = time.perf_counter() >= until
        if bounded:
            count = min(count, BOUNDED_BATCH)
        # popleft, not a copy and clear(): the real-time executor thread may append meanwhile
        handler([queue.popleft() for _ in range(count)])
        took = True
        if bounded:
            return took
    return took


def pending(inputs: Sequence[tuple[deque, Callable[[bytes], None]]]) -> bool:
    return any(queue for queue, _ in inputs)
