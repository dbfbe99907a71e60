"""The serve loop (pdsmc_ros/loop/serve.py) with a stub node: a stall of the loop's own thread after
it took its inputs is a late tick, not an outage of the inputs (they are taken again before it)."""

from __future__ import annotations

import threading
import time

import pytest
from conftest import next_domain

pytest.importorskip("rclpy")
import rclpy  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from std_msgs.msg import Float64  # noqa: E402

from pdsmc_ros.loop.serve import NodeGroup, serve_loop  # noqa: E402

PERIOD = 0.002
STALL = 10 * PERIOD  # the loop thread's stall, once, right after it took a message
STALL_AT_TICK = 100
TICKS = 200


class Ticker:
    """A loop node stub: at each tick, how long ago its newest message was taken."""

    def __init__(self, node: rclpy.node.Node) -> None:
        self.node = node
        self.period = PERIOD
        self.finished = False
        self.exit_code = 0
        self.taken_at: float | None = None
        self.stall_next = False
        self.armed = False
        self.ticks = 0
        self.ages: dict[int, float] = {}  # tick -> age of the newest message (s)

    @property
    def done(self) -> bool:
        """Read by the loop right after it took its inputs: where the stall is put (the GIL held
        by another thread, the CPU taken), once, after the message that armed it."""
        if self.armed:
            self.armed = False
            time.sleep(STALL)
        return self.finished

    @done.setter
    def done(self, value: bool) -> None:
        self.finished = value

    def on_message(self, _data: bytes) -> None:
        self.taken_at = time.perf_counter()
        if self.stall_next:
            self.stall_next, self.armed = False, True

    def tick(self, _lateness: float) -> None:
        self.ticks += 1
        if self.taken_at is not None:
            self.ages[self.ticks] = time.perf_counter() - self.taken_at
        if self.ticks == STALL_AT_TICK:
            self.stall_next = True
        self.finished = self.ticks >= TICKS


@pytest.mark.timeout(60)
def test_a_stall_after_taking_the_inputs_is_followed_by_fresh_inputs_at_the_tick() -> None:
    context = rclpy.Context()
    rclpy.init(context=context, domain_id=next_domain())
    try:
        node = rclpy.create_node("serve_stub", context=context)
        # the loop's input on a companion node the executor does not spin, as Inputs makes it
        io_node = rclpy.create_node("serve_stub_io", context=context)
        sub = io_node.create_subscription(Float64, "/stub_state", lambda _m: None, 1, raw=True)
        pub = node.create_publisher(Float64, "/stub_state", 1)
        ticker = Ticker(node)
        stop = threading.Event()

        def publish() -> None:  # a driver's states, every half period
            while not stop.is_set():
                pub.publish(Float64(data=1.0))
                time.sleep(PERIOD / 2)

        publisher = threading.Thread(target=publish, daemon=True)
        publisher.start()
        executor = SingleThreadedExecutor(context=context)
        executor.add_node(node)
        try:
            serve_loop(executor, NodeGroup([ticker]), [(sub, ticker.on_message)], PERIOD)
        finally:
            stop.set()
            publisher.join(timeout=2)
            executor.shutdown()
        assert ticker.ticks == TICKS
        stalled = [tick for tick in ticker.ages if tick > STALL_AT_TICK]
        first_after = min(stalled)
        # the message taken before the stall is 10 periods old at the tick; the one taken again is fresh
        assert ticker.ages[first_after] < STALL / 2, (first_after, ticker.ages[first_after])
    finally:
        rclpy.try_shutdown(context=context)
