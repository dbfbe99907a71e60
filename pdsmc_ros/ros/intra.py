"""Intra-process delivery between composed nodes (``composed --intra-process``).

rclcpp's component containers can hand messages between nodes of one process
without DDS (``use_intra_process_comms``); rclpy has no such path, so a composed
lockstep step still paid Fast DDS a write per message and a take per subscriber
(about 14 us + 10 us each, 40-50 % of a composed step). This module is that path
for the loop's serialized messages:

* a publisher of a volatile topic (:class:`~pdsmc_ros.ros.publishers.GuardedPublisher`)
  gets a :class:`Route`: each message is appended to the queue of every subscriber
  of that topic in this process, and written to DDS only while a subscriber
  outside the process is matched (``get_subscription_count`` of the DDS
  publisher, which sees no local reader; re-read every ``COUNT_REFRESH_S``);
* a loop input (:class:`~pdsmc_ros.loop.inputs.Inputs`) of a topic that is
  published in this process takes its messages from that queue and has no DDS
  reader; any other input subscribes over DDS as usual. Queues keep every
  message for keep-all subscriptions and the newest ``depth`` for keep-last
  ones, as their DDS reader would.

What stays on DDS: latched (transient-local) topics, the ``/clock`` time source
and everything with a peer in another process -- the DDS publishers remain, so
the graph and tools such as ``ros2 topic echo`` keep working. A message
published from a thread other than the loop's (the real-time executor thread)
triggers a guard condition in the loop's wait set. Messages are the same CDR
bytes either way; the end-to-end test checks a composed run with this path
against the in-process simulation to 1e-9.
"""

from __future__ import annotations

import threading
import time
from collections import deque
from collections.abc import Callable
from typing import Any

from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile

from .. import rclpy_internals as _rclpy_impl

COUNT_REFRESH_S = 0.05  # how often a route re-reads its DDS subscriber count while publishing (a read
# costs about a step; the start-up waits read the count directly)


class Route:
    """Where one publisher's messages go in this process (see the module docstring)."""

    __slots__ = ("publisher", "msg_type", "queues", "external", "next_count", "domain")

    def __init__(self, publisher: Any, msg_type: Any, domain: IntraProcess) -> None:
        self.publisher = publisher  # the rclpy Publisher (its DDS writer)
        self.msg_type = msg_type
        self.queues: list[deque] = []
        self.external = 0
        self.next_count = 0.0
        self.domain = domain

    def deliver(self, data: bytes) -> bool:
        """Queue ``data`` for every local subscriber; whether DDS must carry it too."""
        for queue in self.queues:
            queue.append(data)
        if self.queues and threading.get_ident() != self.domain.loop_thread:
            self.domain.wake()
        now = time.perf_counter()
        if now >= self.next_count:
            self.refresh()
            self.next_count = now + COUNT_REFRESH_S
        return self.external > 0

    def refresh(self) -> int:
        """Re-read the number of matched DDS subscribers (all outside this process)."""
        self.external = self.publisher.get_subscription_count()
        return self.external


class IntraProcess:
    """The intra-process routes of one composed process.

    Publishers and subscriptions register while the nodes are built;
    :meth:`bind` then connects every subscription whose topic (and type) has a
    volatile publisher here to that publisher's route, and subscribes the rest
    over DDS.
    """

    def __init__(self, context: Any) -> None:
        self.routes: dict[str, list[Route]] = {}
        self.pending: list[tuple[str, Any, QoSProfile, Callable[[deque], None], Callable[[], None]]] = []
        self.guard = _rclpy_impl.WakeUp(context)
        self.loop_thread = threading.get_ident()
        self.bound = False

    def add_publisher(self, publisher: Any, msg_type: Any, qos: QoSProfile) -> Route | None:
        """A route for ``publisher``, or None if its topic stays on DDS only (latched)."""
        if qos.durability != DurabilityPolicy.VOLATILE:
            return None
        route = Route(publisher, msg_type, self)
        self.routes.setdefault(publisher.topic_name, []).append(route)
        return route

    def add_subscription(self, topic: str, msg_type: Any, qos: QoSProfile, *,
                         local: Callable[[deque], None], dds: Callable[[], None]) -> None:
        """Register a loop input; at :meth:`bind`, ``local(queue)`` or ``dds()`` is called."""
        if self.bound:
            raise RuntimeError("intra-process subscriptions must be made before bind()")
        self.pending.append((topic, msg_type, qos, local, dds))

    def bind(self) -> dict[str, int]:
        """Connect the registered inputs; returns how many local subscribers each topic got."""
        self.bound = True
        local_counts: dict[str, int] = {}
        for topic, msg_type, qos, local, dds in self.pending:
            routes = [r for r in self.routes.get(topic, ()) if r.msg_type is msg_type]
            if not routes:
                dds()
                continue
            depth = None if qos.history == HistoryPolicy.KEEP_ALL else max(1, qos.depth)
            queue: deque = deque(maxlen=depth)
            for route in routes:
                route.queues.append(queue)
            local(queue)
            local_counts[topic] = local_counts.get(topic, 0) + 1
        self.pending.clear()
        return local_counts

    def wake(self) -> None:
        """End the loop's wait (a message was queued from another thread)."""
        self.guard.trigger()

    def destroy(self) -> None:
        self.routes.clear()
        self.guard.destroy()


_current: IntraProcess | None = None


def current() -> IntraProcess | None:
    """The intra-process domain of the nodes being built in this process, if any."""
    return _current


def activate(domain: IntraProcess | None) -> None:
    """Make ``domain`` the one publishers and inputs built from now on join (None: none)."""
    global _current
    _current = domain
