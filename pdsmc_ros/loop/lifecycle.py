"""Process lifecycle of the nodes: exit statuses, the teardown watch, upstream watches."""

from __future__ import annotations

import faulthandler
import signal
import sys
import time
from collections.abc import Callable
from typing import Any

from rclpy.lifecycle import LifecycleNode, LifecycleState, ManagedEntity, TransitionCallbackReturn
from rclpy.node import Node

from ..ros.topics import TOPIC_JOINT_STATES

EXIT_OK = 0
EXIT_FAILURE = 1
EXIT_BAD_INPUT = 2


# --------------------------------------------------------------------------- #
# Process lifecycle
# --------------------------------------------------------------------------- #
TEARDOWN_TIMEOUT_S = 4.0  # below the orchestration's 5 s between SIGINT and SIGKILL
DRAIN_TIMEOUT_S = 2.0  # at most this long for subscribers to acknowledge the last messages


# Exit status of a node whose work was done but whose DDS teardown hung: its teardown watch
# ends it with SIGALRM (128 + 14 to the shell). scripts/run_experiment.sh reports it as a
# warning, not a failure: the node's outputs were complete before the hang.
EXIT_TEARDOWN_HUNG = 128 + signal.SIGALRM


def arm_teardown_watch(code: int, seconds: float = TEARDOWN_TIMEOUT_S) -> None:
    """End the process, with every thread's stack on stderr, if it has not ended in ``seconds``.

    Armed once the node's work is saved, before DDS entities are destroyed and
    the interpreter finalises (Fast DDS in these wheels hangs there now and
    then, once in a destroy_node). The stack dump runs in faulthandler's own C
    thread, so it fires even when the hang holds the GIL, and names where the
    process was stuck. If the work ended well (``code`` 0) the process is then
    ended by SIGALRM's default action, which needs no Python either, so the
    orchestration can tell a hang after a complete run (:data:`EXIT_TEARDOWN_HUNG`)
    from a failure; otherwise faulthandler exits with status 1. It stays armed
    until the process ends: :func:`run_nodes` is a process entry point.
    """
    if code == EXIT_OK:
        faulthandler.dump_traceback_later(seconds, exit=False, file=sys.__stderr__)
        signal.signal(signal.SIGALRM, signal.SIG_DFL)
        signal.setitimer(signal.ITIMER_REAL, seconds + 0.2)
    else:
        faulthandler.dump_traceback_later(seconds, exit=True, file=sys.__stderr__)


WATCH_GRACE_S = 1.0
"""How much later than its period a tick checks the graph itself, when its loop had no spare time."""


class UpstreamWatch:
    """Real time: notice that every publisher of a topic has gone after the run began.

    A real-time node cannot tell the plant's last message from any other; when
    the plant leaves (its participant is removed from the graph), the node
    downstream of it is done, even if that last message was never delivered.
    The owner calls :meth:`poll` in its loop's spare time (``idle``) and, in case the
    loop has none, :meth:`poll` with ``grace`` from its tick; it reads the graph cache
    (``count_publishers``) at most every ``period`` seconds. (An executor timer did
    this at first: each of its turns took the GIL for about half a millisecond and
    made every hundredth controller period late.)
    """

    def __init__(self, node: Node, topic: str, on_gone: Callable[[], None], *,
                 period: float = 0.1) -> None:
        self.node = node
        self.topic = node.resolve_topic_name(topic)
        self.on_gone = on_gone
        self.period = period
        self.seen = False
        self.gone = False
        self.next_check = 0.0

    def poll(self, grace: float = 0.0) -> None:
        """Check the graph if ``period`` (plus ``grace``) has passed since the last check."""
        now = time.perf_counter()
        if self.gone or now < self.next_check + grace:
            return
        self.next_check = now + self.period
        self.check()

    def check(self) -> None:
        if self.node.count_publishers(self.topic):
            self.seen = True
        elif self.seen:
            self.gone = True
            self.on_gone()


def end_when_plant_leaves(wrapper: Any, received: Callable[[], int]) -> UpstreamWatch:
    """Real time: once the plant has left, no state will come, so ``wrapper`` is done.

    ``received()`` gives the number of states the node received, for the log line.
    Composed with the plant in one process, the plant's node stays in the graph
    until the process ends: :class:`~pdsmc_ros.loop.serve.NodeGroup` calls the watch's ``on_gone`` once
    the plant is done instead.
    """

    def on_gone() -> None:
        if not wrapper.done:
            wrapper.node.get_logger().info(f"the plant has left ({received()} states received); stopping")
            wrapper.done = True

    return UpstreamWatch(wrapper.node, TOPIC_JOINT_STATES, on_gone)


class CommandingEntity(ManagedEntity):
    """The managed-node transitions of a node that commands a robot (ros2_control's controller
    lifecycle): it commands only while active, and leaving the active state (deactivate,
    shutdown, error) publishes one zero command. Subclasses set ``node``, ``active``, ``done``
    and implement :meth:`stop_commanding`, :meth:`configure` and :meth:`cleanup`."""

    node: LifecycleNode
    active: bool
    done: bool

    def stop_commanding(self, why: str) -> bool:
        raise NotImplementedError

    def configure(self) -> None:
        raise NotImplementedError

    def cleanup(self) -> None:
        raise NotImplementedError

    def on_configure(self, state: LifecycleState) -> TransitionCallbackReturn:  # noqa: ARG002
        self.configure()
        return TransitionCallbackReturn.SUCCESS

    def on_activate(self, state: LifecycleState) -> TransitionCallbackReturn:  # noqa: ARG002
        self.active = True
        self.node.get_logger().info("active: commanding")
        return TransitionCallbackReturn.SUCCESS

    def on_deactivate(self, state: LifecycleState) -> TransitionCallbackReturn:  # noqa: ARG002
        self._leave("deactivated")
        return TransitionCallbackReturn.SUCCESS

    def on_cleanup(self, state: LifecycleState) -> TransitionCallbackReturn:  # noqa: ARG002
        self.cleanup()
        return TransitionCallbackReturn.SUCCESS

    def on_shutdown(self, state: LifecycleState) -> TransitionCallbackReturn:  # noqa: ARG002
        self._leave("shut down")
        self.done = True
        return TransitionCallbackReturn.SUCCESS

    def on_error(self, state: LifecycleState) -> TransitionCallbackReturn:  # noqa: ARG002
        self._leave("lifecycle error")
        return TransitionCallbackReturn.SUCCESS

    def _leave(self, why: str) -> None:
        self.active = False
        self.stop_commanding(why)
