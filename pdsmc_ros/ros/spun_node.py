"""A plain rclpy node in a context of its own, spun by a thread: a client of a running graph.

What the tests and the benchmarks drive the nodes with (states and commands recorded by its
subscriptions, goals and services sent through :meth:`SpunNode.call`), as a user's script or
a motion planner's client would: nothing of the package's own wiring, only rclpy.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from typing import Any

import rclpy
import rclpy.executors

SPIN_TIMEOUT_S = 0.005  # the spin thread's longest wait before it looks at ``stop`` (and lets ``call`` in)


def wait_until(condition: Callable[[], object], seconds: float, poll: float = 0.01) -> bool:
    """Whether ``condition()`` became true within ``seconds`` (polled every ``poll`` s)."""
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        if condition():
            return True
        time.sleep(poll)
    return bool(condition())


class SpunNode:
    """A node ``name`` on ROS domain ``domain``, spun by a daemon thread until :meth:`close`.

    Its context is its own (``rclpy.init(context=..., domain_id=domain)``), so several clients
    and tests in one process never share a domain or an executor.
    """

    def __init__(self, domain: int, name: str) -> None:
        self.context = rclpy.Context()
        rclpy.init(args=[], context=self.context, domain_id=domain)  # not the script's command line
        self.node = rclpy.create_node(name, context=self.context)
        self.executor = rclpy.executors.SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.stop = threading.Event()
        self.spinning = threading.Lock()
        self.thread = threading.Thread(target=self._spin, name=f"{name}_spin", daemon=True)
        self.thread.start()

    def _spin(self) -> None:
        while not self.stop.is_set():
            with self.spinning:
                if self.stop.is_set():  # closed while this thread waited for the lock: the node is gone
                    return
                self.executor.spin_once(timeout_sec=SPIN_TIMEOUT_S)
            time.sleep(0)  # let ``call`` take the lock between two turns

    def call(self, make: Callable[[], Any], seconds: float = 30.0, why: Callable[[], str] = lambda: "") -> Any:
        """Send a request (a goal, a result, a cancel, a service call: ``make()`` returns its future)
        and return its answer, waiting at most ``seconds`` (a TimeoutError with ``why()`` if none).

        The request is sent while the spin thread is paused: rclpy's ActionClient files a
        request's future only after sending it, and an answer handled in between would be
        dropped as unexpected.
        """
        with self.spinning:
            future = make()
        return self.wait_for(future, seconds, why)

    def wait_for(self, future: Any, seconds: float = 30.0, why: Callable[[], str] = lambda: "") -> Any:
        """``future``'s result, waited for at most ``seconds``."""
        if not wait_until(future.done, seconds):
            raise TimeoutError(f"no answer within {seconds:g} s\n{why()}".rstrip())
        return future.result()

    wait = staticmethod(wait_until)

    def close(self) -> None:
        """Stop the spin thread, destroy the node's action clients (``destroy_node`` leaves them)
        and the node, and shut its context down."""
        self.stop.set()
        # between two turns of the spin thread, which then ends: on a loaded machine a join with a
        # timeout could return with it still spinning, and a destroyed action client in its wait set
        # raised in that thread
        with self.spinning:
            for waitable in list(self.node.waitables):
                destroy = getattr(waitable, "destroy", None)
                if destroy is not None:
                    destroy()
            self.node.destroy_node()
        self.thread.join(timeout=2)
        rclpy.try_shutdown(context=self.context)
