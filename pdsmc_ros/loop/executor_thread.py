"""Real time: a process's executor (timers, services, parameters, the recorder's flush) spun
in a thread of its own beside the serve loop (:mod:`.serve`), which keeps the loop's
inputs and ticks."""

from __future__ import annotations

import sys
import threading

from rclpy.executors import Executor
from rclpy.node import Node

COLD_WAIT_S = 5.0  # the executor thread's longest sleep (it is woken to stop)


class ExecutorThread:
    """``executor`` spun in a thread of its own from now until :meth:`stop`.

    The thread sleeps until it has work; a guard condition of ``node`` ends that sleep
    when the loop ends (``Executor.wake()`` does not interrupt ``spin_once`` here). Waking
    every 0.1 s instead cost ~0.5 ms under the GIL ten times a second -- a late control
    period each time.
    """

    def __init__(self, executor: Executor, node: Node, *, name: str = "executor") -> None:
        self.executor = executor
        self.node = node
        self.stopping = threading.Event()
        self.wake = node.create_guard_condition(lambda: None)
        self.thread = threading.Thread(target=self._spin, name=name, daemon=True)
        self.thread.start()

    def _spin(self) -> None:
        context = self.node.context
        while not self.stopping.is_set() and context.ok():
            self.executor.spin_once(timeout_sec=COLD_WAIT_S)

    def stop(self) -> None:
        """End the thread: woken now, waited for up to 2 s (a warning if it does not end)."""
        self.stopping.set()
        self.wake.trigger()  # end its wait now
        self.thread.join(timeout=2.0)
        if self.thread.is_alive():
            print("warning: the executor thread did not stop within 2 s", file=sys.stderr, flush=True)
        self.node.destroy_guard_condition(self.wake)
